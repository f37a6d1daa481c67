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
141         stdout closed early (``| head -1``): silent, 128 + SIGPIPE as ``cat`` or ``seq``
            give, since the body may have stopped before its end (0 would say complete)
==========  ===========================================================================

:class:`OneLineParser` makes argparse's own errors one line with status 2 and reads every
negative number (``--G -1e4``, ``-inf``) as a value, so that the option's check names its range.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import sys
from collections.abc import Callable

from .run import Interrupts

COMPLETE, FAILED, USAGE, ENDED_EARLY, INTERRUPTED, BROKEN_PIPE = 0, 1, 2, 3, 130, 141

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


def run(prog: str, body: Callable[[], int | None], *, on_interrupt: str = "") -> int:
    """Run a command's ``body`` and return its exit status (see the module docstring).

    ``on_interrupt`` is added to the interruption line (how to resume: say it only where a
    checkpoint was written; a ``KeyboardInterrupt("message")`` replaces it). An exception whose
    ``ends`` (objects with ``line()`` and ``kind``) and ``written`` (the files) are set ended
    early: one line per end, status 3; without ``written`` it failed. (What SUNDIALS prints
    is captured by :mod:`runkit.ida` and carried by the failure's message.)
    """
    try:
        with Interrupts(defer=False):        # SIGTERM is a KeyboardInterrupt too
            status = int(body() or 0)
            sys.stdout.flush()               # a closed pipe shows here, not at the exit
            return status
    except BrokenPipeError:
        # the reader is gone: the interpreter's last flush must not try again
        with contextlib.suppress(OSError, ValueError):       # a stdout with no file
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return BROKEN_PIPE
    except ValueError as exc:
        print(f"{prog}: error: {one_line(exc)}", file=sys.stderr)
        return USAGE
    except (RuntimeError, OSError, ArithmeticError) as exc:
        if getattr(exc, "ends", None) and getattr(exc, "written", None):
            for end in exc.ends:
                print(f"{prog}: {one_line(end.line())}", file=sys.stderr)
            return ENDED_EARLY
        kind = "" if isinstance(exc, (RuntimeError, OSError)) else f"{type(exc).__name__}: "
        print(f"{prog}: failed: {kind}{one_line(exc)}", file=sys.stderr)
        return FAILED
    except KeyboardInterrupt as exc:
        note = one_line(exc) if str(exc) else on_interrupt
        print(f"{prog}: interrupted{' (' + note + ')' if note else ''}", file=sys.stderr)
        return INTERRUPTED
