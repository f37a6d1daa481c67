"""Input checks shared by every tier: one clear ``ValueError`` naming the parameter and its range.

Every public function of the toolkit validates what a user can get wrong (a volume fraction at or
above jamming, a negative modulus, a NaN) with these helpers, so that messages read the same
everywhere: ``phi = 0.7 is outside the valid range (0, 0.535) (phi_j of hermes2016)``.
"""

from __future__ import annotations

import math
import struct
import sys
from typing import Callable

import numpy as np


def _fmt(value) -> str:
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        return f"{float(arr):.6g}"
    return f"array of shape {arr.shape}"


def _bound(x: float, closed: bool, side: str) -> str:
    if x is None or (isinstance(x, float) and math.isinf(x)):
        return "inf)" if side == "hi" else "(-inf"
    s = f"{x:.6g}"
    if side == "lo":
        return ("[" if closed else "(") + s
    return s + ("]" if closed else ")")


def check_range(name: str, value, lo: float | None = None, hi: float | None = None, *,
                lo_closed: bool = True, hi_closed: bool = True, note: str = "") -> np.ndarray:
    """Return ``value`` as a float array after checking it is finite and inside ``[lo, hi]``.

    Parameters
    ----------
    name : str
        Parameter name used in the message.
    value : float or array_like
        Value(s) to check; every element must be finite and inside the range.
    lo, hi : float or None
        Bounds (None means unbounded).
    lo_closed, hi_closed : bool
        Whether each bound is included.
    note : str
        Extra context appended to the message (e.g. which material set the bound).

    Raises
    ------
    ValueError
        ``"<name> = <value> is outside the valid range [lo, hi]"`` or ``"<name> must be finite"``.
    """
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {value!r} is not a number") from None
    rng = f"{_bound(lo, lo_closed, 'lo')}, {_bound(hi, hi_closed, 'hi')}"
    suffix = f" ({note})" if note else ""
    if not np.all(np.isfinite(arr)):
        bad = arr[~np.isfinite(arr)] if arr.ndim else arr
        raise ValueError(f"{name} must be finite, got {_fmt(np.ravel(bad)[0])}; valid range {rng}{suffix}")
    bad = np.zeros(arr.shape, dtype=bool)
    if lo is not None:
        bad |= (arr < lo) if lo_closed else (arr <= lo)
    if hi is not None:
        bad |= (arr > hi) if hi_closed else (arr >= hi)
    if np.any(bad):
        first = np.ravel(arr[bad])[0] if arr.ndim else float(arr)
        raise ValueError(f"{name} = {first:.6g} is outside the valid range {rng}{suffix}")
    return arr


def check_positive(name: str, value, note: str = "") -> np.ndarray:
    """Check ``value > 0`` and finite (see :func:`check_range`)."""
    return check_range(name, value, 0.0, None, lo_closed=False, note=note)


def check_nonnegative(name: str, value, note: str = "") -> np.ndarray:
    """Check ``value >= 0`` and finite (see :func:`check_range`)."""
    return check_range(name, value, 0.0, None, note=note)


def available_memory() -> int:
    """Memory the system can give without swapping [bytes] (``MemAvailable``, else physical)."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    import os

    return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))


def check_memory(name: str, value, nbytes: float, fraction: float = 0.5) -> None:
    """Refuse a size whose memory estimate exceeds ``fraction`` of the available memory.

    Parameters
    ----------
    name : str
        The size parameter, e.g. ``"--cells"``.
    value : int
        Its value.
    nbytes : float
        The run's memory estimate at that size [bytes].
    fraction : float
        Share of the available memory a run may take.

    Raises
    ------
    ValueError
        ``"--cells = 100000000 needs about 61 GB (estimate), more than half the 20 GB available"``.
    """
    avail = available_memory()
    if nbytes > fraction * avail:
        raise ValueError(f"{name} = {value} needs about {nbytes / 1e9:.3g} GB (estimate), more "
                         f"than {fraction:.0%} of the {avail / 1e9:.3g} GB available; choose a "
                         "smaller size")


_SIGN = 1 << 63


def _ordered(x: float) -> int:
    """An integer that orders the floats as they are ordered (adjacent floats differ by 1)."""
    i = struct.unpack("<q", struct.pack("<d", x))[0]
    return i if i >= 0 else -(i & (_SIGN - 1))


def _float(k: int) -> float:
    """The float of an :func:`_ordered` integer."""
    if k < 0:
        k = ((-k) | _SIGN) - (1 << 64)
    return struct.unpack("<d", struct.pack("<q", k))[0]


def valid_interval(ok: Callable[[float], bool], x0: float) -> tuple:
    """The interval of valid values around a valid ``x0`` of a one-parameter check ``ok``.

    For a refusal that depends on other parameters (phi_c < phi_j of a material, a scene's hub
    inside its wheel): the range of the parameter the user set, at the others' values. Each side
    is found by bisection over the ordered floats (64 evaluations at most), from ``x0`` out to
    the largest float; the boundary is reported at 6 significant digits, closed when that rounded
    value is valid and open otherwise, 0 for a bound on the subnormals (the checks refuse them).
    The interval is assumed connected (the bounds checked are monotone in the parameter).

    Returns
    -------
    (lo, lo_closed, hi, hi_closed) with None for an unbounded side.
    """
    out = []
    for far in (-sys.float_info.max, sys.float_info.max):
        if ok(far):
            out += [None, True]
            continue
        good, bad = _ordered(x0), _ordered(far)
        while abs(bad - good) > 1:
            mid = (good + bad) // 2
            if ok(_float(mid)):
                good = mid
            else:
                bad = mid
        edge = float(f"{_float(bad):.6g}")
        if not (min(_float(good), _float(bad)) <= edge <= max(_float(good), _float(bad))):
            edge = float(f"{_float(good):.6g}")
        if abs(edge) <= sys.float_info.min:
            edge = 0.0
        out += [edge, ok(edge)]
    return out[0], out[1], out[2], out[3]
