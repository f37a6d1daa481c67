"""Input checks shared by every tier: one clear ``ValueError`` naming the parameter and its range.

Every public function of the toolkit validates what a user can get wrong (a volume fraction at or
above jamming, a negative modulus, a NaN) with these helpers, so that messages read the same
everywhere: ``phi = 0.7 is outside the valid range (0, 0.535) (phi_j of hermes2016)``.
"""

from __future__ import annotations

import math

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
