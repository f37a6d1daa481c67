"""Keep numba's on-disk caches consistent with the shared laws.

numba's ``cache=True`` keys a cached kernel on its own source file only, not on the
``register_jitable`` laws (rheology/laws.py) or the local-update kernel it inlines from other files:
after editing those, a kernel cached earlier would silently keep the old physics. Every module that
compiles kernels using them calls :func:`guard` with its ``__file__`` before its first compile; the
module's numba cache files are dropped whenever the shared sources have changed since they were
written. Installed copies are unaffected (their files do not change); this protects editable
installs during development.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numba

_SOURCES = ("laws.py", "local_update.py")


def source_stamp() -> str:
    """Hash of the shared kernel sources and the numba version."""
    h = hashlib.sha1(numba.__version__.encode())
    here = Path(__file__).parent
    for name in _SOURCES:
        h.update((here / name).read_bytes())
    return h.hexdigest()


def guard(module_file: str) -> None:
    """Drop the numba cache files of ``module_file``'s folder if the shared kernels changed."""
    cache = Path(module_file).parent / "__pycache__"
    stamp_file = cache / f"{Path(module_file).stem}.rheology-stamp"
    stamp = source_stamp()
    try:
        if stamp_file.read_text() == stamp:
            return
    except OSError:
        pass
    stem = Path(module_file).stem
    for f in list(cache.glob(f"{stem}.*.nbi")) + list(cache.glob(f"{stem}.*.nbc")):
        try:
            f.unlink()
        except OSError:
            pass
    try:
        cache.mkdir(exist_ok=True)
        stamp_file.write_text(stamp)
    except OSError:                      # read-only install: nothing cached there to go stale
        pass
