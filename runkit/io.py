"""Result files and checkpoints, shared by every tier: atomic, finite, strict, with normal modes.

- Every result is written to a temporary file in the destination folder and moved into place
  with ``os.replace``, so a reader (or a crash) never sees a half-written CSV, PNG or checkpoint;
  the file gets the user's normal permissions (``0666 & ~umask``), not ``mkstemp``'s 0600.
- Every numeric table and JSON document is checked for finiteness before it is written
  (:func:`check_finite`): a NaN or inf is a ``RuntimeError`` with diagnostics (column, first row,
  count), never a CSV cell. Columns that are undefined by construction (a viscosity at zero
  rate) are declared with ``empty_ok`` and written as empty cells; JSON keys likewise with
  ``nullable`` (written as ``null``: the JSON is always strict).
- A checkpoint keeps its predecessor (``NAME.prev.npz``); :func:`load_checkpoint` names a corrupt
  file as corrupt and falls back to the previous one when it is readable.
- :func:`check_output_path` (a file) and :func:`check_output_dir` (a folder) validate an output
  name (its format, that it can be written) before any work is done, so a
  bad ``--plot fig.xyz`` is refused before the CSV is written.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
import zipfile
from collections.abc import Iterable
from pathlib import Path

import numpy as np


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _atomic(path, write, suffix: str) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix, dir=path.parent)
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise
    return path


# ------------------------------------------------------------------ finiteness
def check_finite(frame, where: str = "result", empty_ok: Iterable[str] = ()) -> None:
    """Raise ``RuntimeError`` if a numeric column of ``frame`` holds NaN or inf.

    Parameters
    ----------
    frame : pandas.DataFrame
        The table about to be written.
    where : str
        What the table is (a file name), for the message.
    empty_ok : iterable of str
        Columns that may hold NaN where the value is undefined by construction (written as empty
        cells); inf is refused everywhere.

    Raises
    ------
    RuntimeError
        ``"<where>: column c has N non-finite values (first nan at row k: time_s = ...)"``.
    """
    empty_ok = set(empty_ok)
    for col in frame.columns:
        values = frame[col]
        if values.dtype.kind not in "fc":
            continue
        arr = values.to_numpy()
        bad = np.isinf(arr) if col in empty_ok else ~np.isfinite(arr)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            context = ", ".join(f"{c} = {frame[c].iloc[k]}" for c in frame.columns[:3] if c != col)
            raise RuntimeError(f"{where}: column {col} has {int(bad.sum())} non-finite value(s) "
                               f"(first {arr[k]} at row {k}: {context}); {where} was not "
                               "written")


def strict_json(obj, where: str = "result", nullable: Iterable[str] = (), on_bad=None):
    """``obj`` with numpy scalars/arrays turned into plain Python, checked for finiteness.

    A non-finite float under a key named in ``nullable`` becomes ``None`` (JSON ``null``);
    anywhere else it raises ``RuntimeError`` naming the key path, and a value of another type
    (not dict, list, tuple, array, bool, number, str, Path or None) raises ``TypeError``.
    ``on_bad(path, value)``, when given, is told of each such value instead, which becomes
    ``None``: a caller that keeps what is valid (the validation report) lists them.
    """
    nullable = set(nullable)

    def bad(path: str, x, exc):
        if on_bad is None:
            raise exc
        on_bad(path.lstrip("."), x)

    def conv(x, key: str, path: str):
        if isinstance(x, dict):
            return {str(k): conv(v, str(k), f"{path}.{k}") for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [conv(v, key, f"{path}[{i}]") for i, v in enumerate(x)]
        if isinstance(x, np.ndarray):
            return conv(x.tolist(), key, path)
        if isinstance(x, (bool, np.bool_)):
            return bool(x)
        if isinstance(x, (int, np.integer)):
            return int(x)
        if isinstance(x, (float, np.floating)):
            x = float(x)
            if math.isfinite(x):
                return x
            if key in nullable:
                return None
            return bad(path, x, RuntimeError(f"{where}: {path.lstrip('.')} = {x!r} is not "
                                             "finite; nothing was written"))
        if x is None or isinstance(x, str):
            return x
        if isinstance(x, Path):
            return str(x)
        return bad(path, x, TypeError(f"{where}: {path.lstrip('.')} has type "
                                      f"{type(x).__name__}, not JSON"))

    return conv(obj, "", "")


# ------------------------------------------------------------------ writers
def atomic_write_text(path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (UTF-8)."""
    return _atomic(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"), ".tmp")


def atomic_write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (e.g. text in another encoding)."""
    return _atomic(path, lambda tmp: Path(tmp).write_bytes(data), ".tmp")


def atomic_write_with(path, write, suffix: str = ".tmp") -> Path:
    """Write ``path`` atomically with a writer of one's own: ``write(tmp_path)`` writes the whole
    file to a temporary path in the same folder (e.g. ``lambda tmp: meshio.write(tmp, mesh)``);
    ``suffix`` is the temporary file's, for writers that choose the format by it."""
    return _atomic(path, write, suffix)


def atomic_savez(path, **arrays) -> Path:
    """Write named arrays to an .npz file atomically (no predecessor kept: for result snapshots;
    checkpoints use :func:`save_checkpoint`)."""
    return _atomic(path, lambda tmp: np.savez(tmp, **arrays), ".npz")


def atomic_write_json(path, obj, *, nullable: Iterable[str] = (), indent: int = 1) -> Path:
    """Write ``obj`` as strict JSON (no NaN/Infinity tokens) atomically.

    Non-finite floats are refused (``RuntimeError``) except under the keys in ``nullable``,
    where they become ``null``: use it for values undefined by construction (say so in the
    README's list of fields).
    """
    data = strict_json(obj, Path(path).name, nullable)
    return atomic_write_text(path, json.dumps(data, indent=indent, allow_nan=False) + "\n")


def atomic_write_csv(path, frame, *, empty_ok: Iterable[str] = (), **kwargs) -> Path:
    """Write a pandas DataFrame to CSV atomically (``index=False`` unless given), after
    :func:`check_finite` (NaN allowed only in ``empty_ok`` columns, written as empty cells).
    Negative zeros of float columns are written as 0.0 (``x + 0.0``; ``shear1d couette --speed
    1e-300`` wrote f_mean = -0.0); ``frame`` itself is not changed."""
    check_finite(frame, Path(path).name, empty_ok)
    floats = [i for i, dt in enumerate(frame.dtypes) if dt.kind == "f"]
    if floats:                                   # by position: duplicate column names are kept
        frame = frame.copy()
        for i in floats:
            frame.isetitem(i, frame.iloc[:, i] + 0.0)
    kwargs.setdefault("index", False)
    return _atomic(path, lambda tmp: frame.to_csv(tmp, **kwargs), ".tmp")


def atomic_savefig(fig, path, **kwargs) -> Path:
    """Save a matplotlib figure atomically (format from the path's suffix)."""
    path = Path(path)
    kwargs.setdefault("dpi", 120)
    kwargs.setdefault("bbox_inches", "tight")
    return _atomic(path, lambda tmp: fig.savefig(tmp, format=path.suffix.lstrip(".") or "png",
                                                 **kwargs), path.suffix)


def figure_formats() -> tuple[str, ...]:
    """File suffixes matplotlib can write (png, pdf, svg, ...)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    return tuple(sorted(FigureCanvasAgg.get_supported_filetypes()))


def check_input_file(label: str, path) -> Path:
    """``path`` as a Path if it is an existing file; else ValueError: ``LABEL 'PATH' not found``
    or ``LABEL 'PATH' is a folder, not a file``."""
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{label} {str(path)!r} is a folder, not a file")
    if not path.is_file():
        raise ValueError(f"{label} {str(path)!r} not found")
    return path


def check_output_path(name: str, path, kinds: Iterable[str]) -> Path:
    """Check, before any work, that an output path has one of the allowed suffixes.

    Parameters
    ----------
    name : str
        The option, e.g. ``"--plot"``.
    path : str or Path
    kinds : iterable of str
        Allowed suffixes without the dot; ``"figure"`` stands for every matplotlib format.

    Raises
    ------
    ValueError
        ``"--plot = 'fig.xyz': format 'xyz' is not one of png, pdf, ..."``.
    """
    allowed = [s for k in kinds for s in (figure_formats() if k == "figure" else [k])]
    if str(path).endswith(("/", os.sep)):
        raise ValueError(f"{name} = {str(path)!r} names a folder (trailing separator), not a "
                         "file")
    p = Path(str(path))
    suffix = p.suffix.lower().lstrip(".")
    if suffix not in allowed:
        raise ValueError(f"{name} = {str(path)!r}: format {suffix or '(none)'!r} is not one of "
                         f"{', '.join(allowed)}")
    if p.exists() and p.is_dir():
        raise ValueError(f"{name} = {str(path)!r} is a folder, not a file")
    _check_writable(name, path, p.parent)
    return p


def _check_writable(name: str, given, folder: Path) -> None:
    """Refuse (ValueError) unless a file can be created in ``folder`` or, where it does not exist
    yet, in its nearest existing ancestor (tried with a temporary file, removed at once: an
    access check is not enough for root or for special file systems such as /proc)."""
    probe = Path(folder) if str(folder) else Path(".")
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    if not probe.is_dir():
        raise ValueError(f"{name} = {str(given)!r}: {probe} is a file, not a folder")
    try:
        fd, tmp = tempfile.mkstemp(prefix=".write-test.", dir=probe)
        os.close(fd)
        os.remove(tmp)
    except OSError as exc:
        raise ValueError(f"{name} = {str(given)!r}: cannot write in {probe} "
                         f"({exc.strerror or type(exc).__name__})") from None


def check_output_dir(name: str, path) -> Path:
    """Check, before any work, that ``path`` is (or can be created as) a writable folder.

    Raises
    ------
    ValueError
        ``"--out = 'x.csv' exists and is not a folder"``, ``"--out = '/proc/x': cannot write
        in /proc (...)"``, or an empty name (which Path would read as the current folder).
    """
    if not str(path).strip():
        raise ValueError(f"{name} = {str(path)!r} is empty: give the output folder's name (use "
                         f"{name} . for the current folder)")
    p = Path(str(path))
    if p.exists() and not p.is_dir():
        raise ValueError(f"{name} = {str(path)!r} exists and is not a folder")
    _check_writable(name, path, p)
    return p


# ------------------------------------------------------------------ checkpoints
def previous_checkpoint(path) -> Path:
    """Where the checkpoint before ``path`` is kept (``NAME.prev.npz``)."""
    path = Path(path)
    return path.with_name(path.name.removesuffix(".npz") + ".prev.npz")


def save_checkpoint(path, **arrays) -> Path:
    """Write named numpy arrays (and scalars) to an .npz checkpoint atomically; the checkpoint it
    replaces is kept as :func:`previous_checkpoint` (the fallback of :func:`load_checkpoint`)."""
    path = Path(path)

    def write(tmp):
        np.savez(tmp, **arrays)
        if path.exists():
            os.replace(path, previous_checkpoint(path))

    return _atomic(path, write, ".npz")


def remove_checkpoint(path) -> list[Path]:
    """Remove the checkpoint ``path`` and its predecessor (a completed run keeps neither);
    returns the files removed."""
    gone = [p for p in (Path(path), previous_checkpoint(path)) if p.is_file()]
    for p in gone:
        p.unlink()
    return gone


class CorruptCheckpoint(ValueError):
    """A checkpoint that cannot be read (truncated, not an npz, missing arrays)."""


def _read_npz(path: Path, required: Iterable[str]) -> dict[str, np.ndarray]:
    try:
        with np.load(path, allow_pickle=False) as data:
            out = {k: data[k] for k in data.files}
    except (zipfile.BadZipFile, EOFError, OSError, ValueError, KeyError) as exc:
        reason = ("not an .npz archive" if "pickle" in str(exc) else
                  f"{type(exc).__name__}: {' '.join(str(exc).split())[:120]}")
        raise CorruptCheckpoint(f"checkpoint {path} is corrupt ({reason})") from None
    missing = [k for k in required if k not in out]
    if missing:
        raise CorruptCheckpoint(f"checkpoint {path} is corrupt (missing {', '.join(missing)})")
    return out


def load_checkpoint(path, *, required: Iterable[str] = (), log=None) -> dict[str, np.ndarray]:
    """The arrays of :func:`read_checkpoint` (without the file they were read from)."""
    return read_checkpoint(path, required=required, log=log)[0]


def read_checkpoint(path, *, required: Iterable[str] = (),
                    log=None) -> tuple[dict[str, np.ndarray], Path]:
    """Read a checkpoint written by :func:`save_checkpoint` into a dict of arrays, with the file
    it was read from (``path`` or its :func:`previous_checkpoint`).

    If ``path`` is unreadable and the previous checkpoint is readable, that one is returned and
    ``log`` (a callable) is told so.

    Raises
    ------
    ValueError
        No checkpoint at ``path`` (``"no checkpoint at ..."``).
    CorruptCheckpoint (a ValueError)
        ``path`` is corrupt and no readable previous checkpoint is kept.
    """
    path = Path(path)
    required = tuple(required)
    prev = previous_checkpoint(path)
    if not path.is_file():
        if prev.is_file():                           # stopped between the rotation and the move
            return _read_npz(prev, required), prev
        raise ValueError(f"--resume: no checkpoint at {path}; run without --resume to start")
    try:
        return _read_npz(path, required), path
    except CorruptCheckpoint as exc:
        if not prev.is_file():
            raise CorruptCheckpoint(f"{exc}; no previous checkpoint is kept: start again without "
                                    "--resume") from None
        try:
            data = _read_npz(prev, required)
        except CorruptCheckpoint as exc2:
            raise CorruptCheckpoint(f"{exc}; the previous one too ({exc2})") from None
        if log is not None:
            log(f"{exc}; resuming from the previous checkpoint {prev}")
        return data, prev
