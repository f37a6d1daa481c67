"""A command's outcome: one line on stderr and one exit status, the same in every tier.

==========  ===========================================================================
status      meaning
==========  ===========================================================================
0           complete
1           failed (``RuntimeError``, ``OSError``, ``ArithmeticError``): ``PROG: failed: ...``
2           bad input (``ValueError``, argparse): ``PROG: error: ...``, nothing written
3           ended early: results up to a limit of the model's validity or a solver
            failure written (an exception with ``ends`` and ``written``), one line per end
130         interrupted (Ctrl-C, or SIGTERM turned into the same ``KeyboardInterrupt``)
==========  ===========================================================================

:class:`OneLineParser` makes argparse's own errors one line with status 2 and reads every
negative number (``--G -1e4``, ``-inf``) as a value, so that the option's check names its range.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import re
import signal
import sys
from collections.abc import Callable

COMPLETE, FAILED, USAGE, ENDED_EARLY, INTERRUPTED = 0, 1, 2, 3, 130

#: a negative number as a word of a command line (argparse's own takes only -1 and -.5)
NEGATIVE_NUMBER = re.compile(r"^-(?:(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|inf|infinity|nan)$",
                             re.IGNORECASE)


class OneLineParser(argparse.ArgumentParser):
    """argparse with one-line usage errors (status 2) that reads negative numbers as values;
    subparsers made with ``add_subparsers(parser_class=OneLineParser)`` get the same."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NEGATIVE_NUMBER

    def error(self, message):
        self.exit(USAGE, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def one_line(exc: BaseException) -> str:
    """The exception's message on one line (its type name if it has none)."""
    return " ".join(str(exc).split()) or type(exc).__name__


def _sigterm(signum, frame):
    raise KeyboardInterrupt


class SundialsFilter(io.TextIOBase):
    """stdout without the error lines of sksundae's SUNDIALS error handler.

    sksundae (1.2) prints every SUNDIALS error with ``print`` on stdout (``[IDASolve, Error:
    -22] At t = ...`` between blank lines) besides returning the failed status the tiers turn
    into their own one-line error. Those lines (and the blank lines around them) are kept in
    ``caught`` for that message (:func:`run` appends the last); every other line passes."""

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
            self._blanks += not self._after_error
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

    def close_stream(self):
        """Flush, and write the blank lines held back after the last line."""
        self.flush()
        if self._blanks and not self._after_error:
            self.stream.write("\n" * self._blanks)


def run(prog: str, body: Callable[[], int | None], *, on_interrupt: str = "") -> int:
    """Run a command's ``body`` and return its exit status (see the module docstring).

    ``on_interrupt`` is added to the interruption line (how to resume: say it only where a
    checkpoint was written; a ``KeyboardInterrupt("message")`` replaces it). An exception whose
    ``ends`` (objects with ``line()`` and ``kind``) and ``written`` (the files) are set ended
    early: one line per end, status 3; without ``written`` it failed. SUNDIALS' own error lines
    on stdout are caught (:class:`SundialsFilter`); the last is added to a failure's line.
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
        sundials = f" [SUNDIALS: {out.caught[-1].lstrip('[')}" if out.caught else ""
        if getattr(exc, "ends", None) and getattr(exc, "written", None):
            for end in exc.ends:
                tail = sundials if getattr(end, "kind", "") == "solver_failure" else ""
                print(f"{prog}: {one_line(end.line())}{tail}", file=sys.stderr)
            return ENDED_EARLY
        kind = "" if isinstance(exc, (RuntimeError, OSError)) else f"{type(exc).__name__}: "
        print(f"{prog}: failed: {kind}{one_line(exc)}{sundials}", file=sys.stderr)
        return FAILED
    except KeyboardInterrupt as exc:
        note = one_line(exc) if str(exc) else on_interrupt
        print(f"{prog}: interrupted{' (' + note + ')' if note else ''}", file=sys.stderr)
        return INTERRUPTED
    finally:
        out.close_stream()
        signal.signal(signal.SIGTERM, previous)
