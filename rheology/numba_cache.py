"""Keep numba's on-disk caches consistent with the sources their kernels use.

numba's ``cache=True`` keys a cached kernel on its own source file only, not on the functions it
calls or inlines from other files: the ``register_jitable`` laws (rheology/laws.py) with their
log and exp (rheology/vecmath.py), the local-update kernel, or a sibling module's helpers
(mpm2d.shape's B-spline stencil inside mpm2d.transfer's kernels). After editing those, a
kernel cached earlier would silently keep the old code. Every module that compiles cached
kernels calls :func:`guard` with its ``__file__`` (and the files of other packages it calls
into) before its first compile; the module's numba cache files are dropped whenever the shared
rheology kernels or any module of those packages (the ``*.py`` files of their folders) changed
since they were written. Installed copies are unaffected (their files do not change); this
protects editable installs during development.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numba

_SOURCES = ("laws.py", "local_update.py", "roots.py", "vecmath.py")


def source_stamp(folders=()) -> str:
    """Hash of the shared kernel sources, every ``*.py`` directly in ``folders`` (sorted) and
    the numba version."""
    h = hashlib.sha1(numba.__version__.encode())
    here = Path(__file__).parent
    files = [here / name for name in _SOURCES]
    for folder in sorted({Path(f).resolve() for f in folders}):
        files += sorted(folder.glob("*.py"))
    for f in files:
        h.update(f.name.encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def guard(module_file: str, *depends_on: str) -> None:
    """Drop the numba cache files of ``module_file`` if the shared kernels, a module of its own
    package or of the packages of ``depends_on`` (module files) changed since they were
    written."""
    cache = Path(module_file).parent / "__pycache__"
    stamp_file = cache / f"{Path(module_file).stem}.rheology-stamp"
    stamp = source_stamp([Path(f).parent for f in (module_file,) + depends_on])
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
