"""What the toolkit's command lines (``rheometer``, ``shear1d``, ``mpm2d``) share: one-line errors
and one mapping from exceptions to exit statuses.

- bad input (``ValueError``, a usage error): ``PROG: error: ...``, status 2;
- a solver or file failure (``RuntimeError``, ``OSError``): ``PROG: failed: ...``, status 1;
- Ctrl-C or SIGTERM: ``PROG: interrupted ...``, status 130.

Every message is one line on stderr, never a traceback.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable

USAGE, FAILED, INTERRUPTED = 2, 1, 130


class OneLineParser(argparse.ArgumentParser):
    """argparse whose usage errors are one line (no usage block) with status 2."""

    def error(self, message):
        self.exit(USAGE, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def one_line(exc: BaseException) -> str:
    """The exception's message on one line (its type name if it has none)."""
    return " ".join(str(exc).split()) or type(exc).__name__


def run_command(prog: str, body: Callable[[], int | None], *, on_interrupt: str = "") -> int:
    """Run ``body`` and return the exit status (``body``'s return value, or 0).

    Parameters
    ----------
    prog : str
        Prefix of the messages, e.g. ``"shear1d annular"``.
    body : callable
        The command; raises ValueError for bad input, RuntimeError or OSError on failure.
    on_interrupt : str
        Added to the interruption message, e.g. how to resume.
    """
    try:
        return int(body() or 0)
    except ValueError as exc:
        print(f"{prog}: error: {one_line(exc)}", file=sys.stderr)
        return USAGE
    except (RuntimeError, OSError) as exc:
        print(f"{prog}: failed: {one_line(exc)}", file=sys.stderr)
        return FAILED
    except KeyboardInterrupt:
        print(f"{prog}: interrupted{' (' + on_interrupt + ')' if on_interrupt else ''}",
              file=sys.stderr)
        return INTERRUPTED
