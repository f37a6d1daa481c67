"""Serial and parallel builds of every numba kernel.

A parallel numba loop costs tens of microseconds to launch (much more on a loaded machine), which
dominates small models such as the verification problems. Each kernel is therefore compiled
twice from the same source, once with ``parallel=True`` (``prange`` over chunks or points) and
once serially (``prange`` acts as ``range``, and without numba's reference counting, so a
kernel must not allocate arrays), both cached on disk under distinct names;
:class:`~mpm2d.simulation.Simulation` picks the parallel build above :data:`PARALLEL_MIN_POINTS`
points. Both builds do the same arithmetic in the same order, so results are identical.
"""

from __future__ import annotations

import types

import numba as nb

#: models with at least this many points (or grid nodes) use the parallel builds
PARALLEL_MIN_POINTS = 20000


class Dual:
    """``kernel[parallel]`` -> the serial (False) or parallel (True) dispatcher."""

    def __init__(self, fn):
        self.py_func = fn
        self._builds = {}
        self.__doc__ = fn.__doc__
        self.__name__ = fn.__name__

    def _build(self, parallel: bool):
        fn = self.py_func
        name = f"{fn.__name__}_{'par' if parallel else 'ser'}"
        f = types.FunctionType(fn.__code__, fn.__globals__, name, fn.__defaults__, fn.__closure__)
        f.__qualname__ = name
        f.__module__ = fn.__module__
        f.__doc__ = fn.__doc__
        # the serial build without numba's reference counting: it would incref and decref the
        # arrays of every inlined helper once per loop iteration (atomic operations, which the
        # parallel build's loop bodies do not have); the kernels allocate nothing
        return nb.njit(cache=True, parallel=parallel, error_model="numpy",
                       **({} if parallel else {"_nrt": False}))(f)

    def __getitem__(self, parallel: bool):
        parallel = bool(parallel)
        if parallel not in self._builds:
            self._builds[parallel] = self._build(parallel)
        return self._builds[parallel]

    def __call__(self, *args):
        return self[True](*args)


def dual(fn) -> Dual:
    """Decorator: compile ``fn`` (which uses ``numba.prange``) serially and in parallel."""
    return Dual(fn)
