"""rheology.numba_cache.guard: a module's numba cache files are dropped when a module of its
package (or of a package it names) changes, and kept otherwise (numba keys a cached kernel on
its own file only: an edited helper in a sibling module would otherwise leave the old code
cached; found with mpm2d.transfer's kernels after an edit of mpm2d.shape)."""

from __future__ import annotations

from pathlib import Path

from rheology.numba_cache import guard


def _cache_files(pkg: Path, stem: str):
    cache = pkg / "__pycache__"
    cache.mkdir(exist_ok=True)
    files = [cache / f"{stem}.k-1.py311.nbi", cache / f"{stem}.k-1.py311.1.nbc"]
    for f in files:
        f.write_bytes(b"cached")
    return files


def test_guard_drops_caches_when_a_sibling_or_a_named_package_changes(tmp_path):
    pkg, other = tmp_path / "pkg", tmp_path / "other"
    pkg.mkdir()
    other.mkdir()
    mod, helper, dep = pkg / "mod.py", pkg / "helper.py", other / "dep.py"
    for f in (mod, helper, dep):
        f.write_text("x = 1\n")
    guard(str(mod), str(dep))                     # first call: writes the stamp
    files = _cache_files(pkg, "mod")
    guard(str(mod), str(dep))
    assert all(f.exists() for f in files)         # nothing changed: kept
    helper.write_text("x = 2\n")
    guard(str(mod), str(dep))
    assert not any(f.exists() for f in files)     # a sibling module changed: dropped
    files = _cache_files(pkg, "mod")
    guard(str(mod), str(dep))
    assert all(f.exists() for f in files)
    dep.write_text("x = 3\n")
    guard(str(mod), str(dep))
    assert not any(f.exists() for f in files)     # the named package changed: dropped
