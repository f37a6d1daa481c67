"""What the toolkit's command lines (``rheometer``, ``shear1d``, ``mpm2d``) share: one validation
path for every option, one-line errors and one mapping from exceptions to exit statuses.

- bad input (``ValueError``, a usage error): ``PROG: error: ...``, status 2, nothing written;
- a solver or file failure (``RuntimeError``, ``OSError``): ``PROG: failed: ...``, status 1;
- Ctrl-C or SIGTERM: ``PROG: interrupted ...``, status 130 (SIGTERM is turned into the same
  ``KeyboardInterrupt`` as Ctrl-C, so every long run saves its checkpoint on both);
- a run that ended early at a validity limit or a solver failure, its rows up to there written
  (:class:`rheology.run_end.EndedEarly`): ``PROG: ended early at t = ...`` per run, status 3.

Every numeric option is declared with :class:`Number` (``type=Number("--t-end", 0, None,
lo_closed=False)``): a NaN, an inf, a value out of range or not a number is refused with
``--t-end = nan: must be finite; valid range (0, inf)``. The property test
``tests/test_cli_bad_input.py`` walks every option of every subcommand and checks that it is so.

Every message is one line on stderr, never a traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import re
import signal
import sys
from collections.abc import Callable

from .run_end import ENDED_EARLY, EndedEarly

USAGE, FAILED, INTERRUPTED = 2, 1, 130


#: What a negative number looks like on a command line: argparse's own matcher takes only ``-1``
#: and ``-.5``, so ``--G -1e4`` or ``--phi -inf`` became "expected one argument" instead of the
#: option's range; this one also takes ``-1e4``, ``-1.5E-3``, ``-inf``, ``-infinity``, ``-nan``.
NEGATIVE_NUMBER = re.compile(r"^-(?:(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|inf|infinity|nan)$",
                             re.IGNORECASE)

#: Durations every tier accepts [s] (a run's end time, a step, a program line): from TIME_MIN = 1
#: ps, the molecular relaxation time of the suspending liquid (water ~1 ps; below it the model's
#: Newtonian fluid, and so the continuum suspension, has no meaning; it also keeps SUNDIALS IDA
#: clear of its stop-time underflow below ~1.5e-154 s), to TIME_MAX = 1e9 s (30 years, past any
#: experiment; it keeps the output times finite: 1e300 s ran for minutes, then failed in IDA).
TIME_MIN, TIME_MAX = 1e-12, 1e9


class OneLineParser(argparse.ArgumentParser):
    """argparse whose usage errors are one line (no usage block) with status 2, and which reads
    every negative number (:data:`NEGATIVE_NUMBER`, e.g. ``--G -1e4``) as a value, so that the
    option's :class:`Number` refuses it with its range. Subparsers made with
    ``add_subparsers(parser_class=OneLineParser)`` get the same."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NEGATIVE_NUMBER

    def error(self, message):
        self.exit(USAGE, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def valid_range(lo, hi, lo_closed=True, hi_closed=True) -> str:
    """``"[lo, hi)"``-style text of a range (None for unbounded)."""
    left = "(-inf" if lo is None else ("[" if lo_closed else "(") + f"{lo:g}"
    right = "inf)" if hi is None else f"{hi:g}" + ("]" if hi_closed else ")")
    return f"{left}, {right}"


class Number:
    """An argparse ``type`` (and a checker) for a finite number in a range.

    Parameters
    ----------
    name : str
        The option's name, e.g. ``"--t-end"`` (used in the message).
    lo, hi : float or None
        Bounds (None: unbounded).
    integer : bool
        Require an integer (``"3"`` or ``"3.0"``; ``"3.5"`` is refused).
    lo_closed, hi_closed : bool
        Whether the bounds are allowed.
    unit : str
        Appended to the range in the message.
    shown_range : str
        For an option whose bounds depend on the run (the material, phi) and are checked once
        it is known: the range as the parse-time message states it (``lo``/``hi`` then None,
        so that only finiteness is checked here), e.g. ``"(0, 0.1 sqrt(G/rho)]"``.

    Raises
    ------
    argparse.ArgumentTypeError (through argparse: one line, status 2), or ValueError from
    :meth:`check`.
    """

    def __init__(self, name: str, lo=None, hi=None, *, integer: bool = False,
                 lo_closed: bool = True, hi_closed: bool = True, unit: str = "",
                 shown_range: str = ""):
        if shown_range and (lo is not None or hi is not None):
            raise ValueError(f"{name}: shown_range is for bounds checked later (lo = hi = None)")
        self.name, self.lo, self.hi, self.integer = name, lo, hi, integer
        self.lo_closed, self.hi_closed, self.unit = lo_closed, hi_closed, unit
        self.shown_range = shown_range
        self.__name__ = "integer" if integer else "number"      # argparse's "invalid X value"

    @property
    def range_text(self) -> str:
        text = self.shown_range or valid_range(self.lo, self.hi, self.lo_closed, self.hi_closed)
        return text + (f" {self.unit}" if self.unit else "")

    def contains(self, x: float) -> bool:
        """Whether ``x`` (a float) is a valid value."""
        if not math.isfinite(x) or (self.integer and x != int(x)):
            return False
        if self.lo is not None and (x < self.lo or (x == self.lo and not self.lo_closed)):
            return False
        if self.hi is not None and (x > self.hi or (x == self.hi and not self.hi_closed)):
            return False
        return True

    def check(self, value):
        """Return ``value`` as int or float, or raise ``ValueError`` naming the option."""
        kind = "an integer" if self.integer else "a number"
        try:
            x = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"{self.name} = {value!r} is not {kind}; valid range "
                             f"{self.range_text}") from None
        # as typed, or compact unless that rounds it (1.531561 is not shown as 1.53156)
        shown = value if isinstance(value, str) else (
            f"{x:.6g}" if float(f"{x:.6g}") == x else repr(x))
        if not math.isfinite(x):
            raise ValueError(f"{self.name} = {shown}: must be finite; valid range "
                             f"{self.range_text}")
        if x != 0.0 and abs(x) < sys.float_info.min:
            raise ValueError(f"{self.name} = {shown} is subnormal (nonzero but below "
                             f"{sys.float_info.min:.3g}, held with lost precision); valid range "
                             f"{self.range_text}")
        if self.integer and x != int(x):
            raise ValueError(f"{self.name} = {shown} is not an integer; valid range "
                             f"{self.range_text}")
        if not self.contains(x):
            raise ValueError(f"{self.name} = {shown} is outside the valid range "
                             f"{self.range_text}")
        return int(x) if self.integer else x

    def __call__(self, text):
        try:
            return self.check(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    def __repr__(self):
        return f"Number({self.name!r}, {self.range_text})"


def one_line(exc: BaseException) -> str:
    """The exception's message on one line (its type name if it has none)."""
    return " ".join(str(exc).split()) or type(exc).__name__


def _sigterm(signum, frame):
    raise KeyboardInterrupt


class SundialsFilter(io.TextIOBase):
    """stdout without the error lines of sksundae's SUNDIALS error handler.

    sksundae (1.2) prints every SUNDIALS error with ``print`` on stdout, e.g.
    ``[IDASolve, Error: -22] At t = ..., ...`` between blank lines, besides returning the failed
    status that the tiers turn into their own one-line RuntimeError. Those lines (and the blank
    lines around them) are kept in ``caught`` instead, for that message (:func:`run_command`
    appends the last); every other line passes through unchanged."""

    LINE = re.compile(r"^\[(IDA|CVode|CVODE|SUN)\w*, Error: -?\d+\] ")

    def __init__(self, stream):
        self.stream, self.caught = stream, []
        self._part, self._blanks, self._after_error = "", 0, False

    def writable(self):
        return True

    def write(self, text):
        self._part += text
        while "\n" in self._part:
            line, self._part = self._part.split("\n", 1)
            self._line(line)
        return len(text)

    def _line(self, line):
        if not line.strip():
            if not self._after_error:
                self._blanks += 1
            return
        if self.LINE.match(line):
            self.caught.append(line.strip())
            self._blanks, self._after_error = 0, True
            return
        self.stream.write("\n" * self._blanks + line + "\n")
        self._blanks, self._after_error = 0, False

    def flush(self):
        if self._part:
            part, self._part = self._part, ""
            if self.LINE.match(part):
                self.caught.append(part.strip())
            else:
                self.stream.write("\n" * self._blanks + part)
                self._blanks = 0
        self.stream.flush()


def run_command(prog: str, body: Callable[[], int | None], *, on_interrupt: str = "") -> int:
    """Run ``body`` and return the exit status (``body``'s return value, or 0).

    SIGTERM raises ``KeyboardInterrupt`` inside ``body`` like Ctrl-C, so a long run writes its
    checkpoint on both (batch schedulers send SIGTERM).

    Parameters
    ----------
    prog : str
        Prefix of the messages, e.g. ``"shear1d annular"``.
    body : callable
        The command; raises ValueError for bad input, RuntimeError or OSError on failure, and
        :class:`~rheology.run_end.EndedEarly` with the files it wrote for a run that ended early.
    on_interrupt : str
        Added to the interruption message, e.g. how to resume. Say it only where a checkpoint
        was really written (a body can raise ``KeyboardInterrupt("message")`` to replace it).
    """
    previous = signal.signal(signal.SIGTERM, _sigterm)
    out = SundialsFilter(sys.stdout)
    try:
        with contextlib.redirect_stdout(out):
            return int(body() or 0)
    except ValueError as exc:
        print(f"{prog}: error: {one_line(exc)}", file=sys.stderr)
        return USAGE
    except (RuntimeError, OSError, ArithmeticError) as exc:
        # ArithmeticError (overflow, division by zero in a library) is the last net under the
        # tiers' own checks: one line, never a traceback
        kind = "" if isinstance(exc, (RuntimeError, OSError)) else f"{type(exc).__name__}: "
        sundials = f" [SUNDIALS: {out.caught[-1].lstrip('[')}" if out.caught else ""
        if isinstance(exc, EndedEarly) and exc.written:
            for end in exc.ends:
                tail = sundials if end.kind == "solver_failure" else ""
                print(f"{prog}: {one_line(end.line())}{tail}", file=sys.stderr)
            return ENDED_EARLY
        print(f"{prog}: failed: {kind}{one_line(exc)}{sundials}", file=sys.stderr)
        return FAILED
    except KeyboardInterrupt as exc:
        note = one_line(exc) if str(exc) else on_interrupt
        print(f"{prog}: interrupted{' (' + note + ')' if note else ''}", file=sys.stderr)
        return INTERRUPTED
    finally:
        out.flush()
        if out._blanks and not out._after_error:
            out.stream.write("\n" * out._blanks)
        signal.signal(signal.SIGTERM, previous)
