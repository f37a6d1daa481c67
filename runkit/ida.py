"""SUNDIALS IDA (through scikit-sundae) with named root events, its printed output captured and
one failure text.

:class:`Solver` wraps ``sksundae.ida.IDA`` for ``F(t, y, y') = 0``: events are given by name
with their direction and whether they stop the solve; :meth:`Solver.advance` steps to an output
time, recording each root by name and continuing past those that do not stop the run;
:meth:`Solver.solve` integrates over a grid of times. Whatever SUNDIALS prints during a call
(sksundae prints its error handler's lines on stdout; C code writes to file descriptors 1 and 2)
is captured (:func:`captured`) and appended to the failure: :class:`IDAFailed`, a RuntimeError
``IDA failed at t = T s (target T1 s): MESSAGE (status S); DIAGNOSTICS [SUNDIALS: ...]``, whose
diagnostics come from the caller's ``describe(t, y)``.
"""

from __future__ import annotations

import contextlib
import ctypes
import io
import os
import sys
import tempfile
from collections.abc import Callable

import numpy as np
from sksundae.ida import IDA

#: IDA's status of a return at a root
ROOT_RETURN = 2


class _Captured:
    text = ""
    libc = tmp = None                    # the C library and one temporary file, reused


@contextlib.contextmanager
def captured():
    """Capture what is printed inside: Python's stdout (sksundae's error lines) and the file
    descriptors 1 and 2 (C code). Yields an object whose ``text`` holds it, on one line."""
    out, buf = _Captured(), io.StringIO()
    saved = None
    try:
        sys.stdout.flush()
        sys.stderr.flush()
        if _Captured.libc is None:
            _Captured.libc, _Captured.tmp = ctypes.CDLL(None), tempfile.TemporaryFile()
        libc, tmp = _Captured.libc, _Captured.tmp
        libc.fflush(None)
        tmp.seek(0)
        tmp.truncate()
        saved = (os.dup(1), os.dup(2))
        os.dup2(tmp.fileno(), 1)
        os.dup2(tmp.fileno(), 2)
    except (OSError, AttributeError, ValueError, io.UnsupportedOperation):
        saved = None                     # no file descriptors to redirect (an embedded stream)
    try:
        with contextlib.redirect_stdout(buf):
            yield out
    finally:
        c_text = ""
        if saved is not None:
            libc.fflush(None)
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])
            if tmp.tell():
                tmp.seek(0)
                c_text = tmp.read(4096).decode("utf-8", "replace")
        out.text = " ".join(f"{buf.getvalue()} {c_text}".split())


class IDAFailed(RuntimeError):
    """An IDA call that did not succeed: ``t`` reached, ``target``, IDA's ``message`` and
    ``status``, what SUNDIALS printed (``printed``), the caller's ``diagnostics`` and ``sol``
    (the outputs reached: the results up to the failure)."""

    def __init__(self, sol, target, printed="", diagnostics="", solver="IDA", t_reached=None):
        t = float(np.atleast_1d(sol.t)[-1])
        if t_reached is not None and not t_reached <= t <= target:
            t = float(t_reached)     # a failed step's t is not always set: the last one reached
        self.sol, self.t = sol, t
        self.target, self.message, self.status = float(target), sol.message, sol.status
        self.printed, self.diagnostics = printed, diagnostics
        super().__init__(f"{solver} failed at t = {self.t:.6g} s (target {self.target:.6g} s): "
                         f"{sol.message} (status {sol.status})"
                         + (f"; {diagnostics}" if diagnostics else "")
                         + (f" [SUNDIALS: {printed.lstrip('[')[:300]}]" if printed else ""))


class Solver:
    """IDA for ``residual(t, y, yp, res)`` (fills ``res``).

    Parameters
    ----------
    residual : callable
    rtol, atol : float, float or array
    events : callable(t, y, yp, out), optional
        The root functions (fills ``out``), one per name of ``names`` (sequence of str).
    direction : sequence of int
        +1 rising, -1 falling, 0 both (default 0).
    stop : sequence of bool
        Whether each event ends a solve (:meth:`solve`); :meth:`advance` stops at the names
        it is given.
    describe : callable(t, y) -> str, optional
        Diagnostics of a failure (the state there).
    solver : str
        How a failure names the solver (``"IDA (method dae)"``).
    band : int, optional
        Half bandwidth of a banded Jacobian.
    **options
        Any other ``sksundae.ida.IDA`` option (``jacfn``, ``algebraic_idx``, ``max_step``,
        ``max_order``, ``max_num_steps``, ...).
    """

    def __init__(self, residual: Callable, *, rtol: float, atol, events: Callable | None = None,
                 names=(), direction=None, stop=None, describe: Callable | None = None,
                 solver: str = "IDA", band: int | None = None, **options):
        self.names = tuple(names)
        self.describe, self.solver_name = describe, solver
        self.printed, self._seen, self.t_reached = "", 0, None
        if band is not None:
            options.update(linsolver="band", lband=int(band), uband=int(band))
        if events is not None:
            def eventsfn(t, y, yp, out):
                events(t, y, yp, out)

            eventsfn.direction = list(direction or [0] * len(self.names))
            eventsfn.terminal = list(stop if stop is not None else [False] * len(self.names))
            options.update(eventsfn=eventsfn, num_events=len(self.names))
        self.ida = IDA(residual, rtol=rtol, atol=atol, **options)

    def _call(self, fn, *args):
        with captured() as c:
            sol = fn(*args)
        self.printed = c.text or self.printed
        return sol

    def _fail(self, sol, target):
        y = np.asarray(sol.y)
        y = y[-1] if y.ndim > 1 else y
        diag = self.describe(float(np.atleast_1d(sol.t)[-1]), y) if self.describe else ""
        return IDAFailed(sol, target, self.printed, diag, self.solver_name, self.t_reached)

    def roots(self, sol) -> list[tuple[float, str, int]]:
        """The roots IDA reported since the last call: (t, name, direction)."""
        te = np.atleast_1d(sol.t_events) if sol.t_events is not None else np.zeros(0)
        ie = np.atleast_2d(sol.i_events) if sol.i_events is not None else np.zeros((0, 0))
        out = [(float(te[k]), name, int(ie[k][i])) for k in range(self._seen, len(te))
               for i, name in enumerate(self.names) if ie[k][i] != 0]
        self._seen = len(te)
        return out

    def start(self, t0: float, y0, yp0) -> None:
        """Initialise at ``t0`` with a consistent (y0, yp0); the roots are counted afresh."""
        self._seen, self.t_reached = 0, float(t0)
        self._call(self.ida.init_step, float(t0), np.asarray(y0, float), np.asarray(yp0, float))

    def advance(self, t: float, stop_on=(), tstop: float | None = None):
        """Step to the output time ``t``, past roots not in ``stop_on``.

        Returns (solution at t or at the stopping root, [(t, name, direction) of the roots]).
        Raises :class:`IDAFailed`.
        """
        fired = []
        while True:
            sol = self._call(self.ida.step, float(t), "normal", tstop)
            if sol.success or sol.status == ROOT_RETURN:
                self.t_reached = float(np.atleast_1d(sol.t)[-1])
            if sol.status == ROOT_RETURN:
                new = self.roots(sol)
                fired += new
                if any(name in stop_on for _, name, _ in new):
                    return sol, fired
                continue
            if not sol.success:
                raise self._fail(sol, t)
            return sol, fired

    def solve(self, times, y0, yp0):
        """Integrate over ``times`` (>= 2, increasing) from a consistent (y0, yp0); stops at an
        event marked ``stop``. Returns (solution, roots); raises :class:`IDAFailed`."""
        times = np.asarray(times, dtype=float)
        if times.size == 2:                         # outputs at the two times, not IDA's steps
            times = np.array([times[0], 0.5 * (times[0] + times[1]), times[1]])
        self._seen = 0
        sol = self._call(self.ida.solve, times, np.asarray(y0, float), np.asarray(yp0, float))
        if not sol.success:
            raise self._fail(sol, times[-1])
        return sol, self.roots(sol)
