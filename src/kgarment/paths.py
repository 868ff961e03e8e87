"""Where kgarment keeps its caches.

``KGARMENT_CACHE_DIR`` moves kgarment's own cache (posed body meshes); it defaults to
``~/.cache/kgarment``. Anny keeps its own model cache in ``ANNY_CACHE_DIR``
(default ``~/.cache/anny``).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np


def cache_dir() -> Path:
    """The kgarment cache folder (created if missing)."""
    root = Path(os.environ.get("KGARMENT_CACHE_DIR", Path.home() / ".cache" / "kgarment"))
    root.mkdir(parents=True, exist_ok=True)
    return root


def atomic_save_npz(path: Path, **arrays) -> None:
    """Write an ``.npz`` file atomically (write to a temporary file, then rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp.npz")
    os.close(fd)
    try:
        np.savez_compressed(tmp, **arrays)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
