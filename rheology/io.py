"""Atomic result files and checkpoints, shared by every tier.

A result is written to a temporary file in the destination folder and moved into place with
``os.replace``, so a reader (or a crash) never sees a half-written CSV, PNG or checkpoint.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np


def _atomic(path, write, suffix: str) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix, dir=path.parent)
    os.close(fd)
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise
    return path


def atomic_write_text(path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (UTF-8)."""
    return _atomic(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"), ".tmp")


def atomic_write_csv(path, frame, **kwargs) -> Path:
    """Write a pandas DataFrame to CSV atomically (``index=False`` unless given)."""
    kwargs.setdefault("index", False)
    return _atomic(path, lambda tmp: frame.to_csv(tmp, **kwargs), ".tmp")


def atomic_savefig(fig, path, **kwargs) -> Path:
    """Save a matplotlib figure atomically (format from the path's suffix)."""
    path = Path(path)
    kwargs.setdefault("dpi", 120)
    kwargs.setdefault("bbox_inches", "tight")
    return _atomic(path, lambda tmp: fig.savefig(tmp, format=path.suffix.lstrip(".") or "png",
                                                 **kwargs), path.suffix)


def save_checkpoint(path, **arrays) -> Path:
    """Write named numpy arrays (and scalars) to an .npz checkpoint atomically."""
    return _atomic(path, lambda tmp: np.savez(tmp, **arrays), ".npz")


def load_checkpoint(path) -> dict[str, np.ndarray]:
    """Read a checkpoint written by :func:`save_checkpoint` into a dict of arrays."""
    with np.load(Path(path), allow_pickle=False) as data:
        return {k: data[k] for k in data.files}
