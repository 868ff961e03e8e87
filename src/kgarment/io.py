"""Files: kgarment's cache folder and the one atomic writer every module uses.

``KGARMENT_CACHE_DIR`` moves kgarment's own cache (posed body meshes); it defaults to
``~/.cache/kgarment``. Anny keeps its own model cache in ``ANNY_CACHE_DIR``
(default ``~/.cache/anny``).

Every file kgarment writes goes through :func:`atomic_write_bytes` (write a temporary file
in the same folder, then rename it over the target), so a killed process never leaves a
half-written checkpoint, metrics table or mesh behind.
"""

from __future__ import annotations

import io
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from kgarment.errors import KgarmentError


def cache_dir() -> Path:
    """The kgarment cache folder (created if missing)."""
    root = Path(os.environ.get("KGARMENT_CACHE_DIR", Path.home() / ".cache" / "kgarment"))
    root.mkdir(parents=True, exist_ok=True)
    return root


def atomic_write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (parent folders are created)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def atomic_write_text(path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    return atomic_write_bytes(path, text.encode())


def atomic_save_npz(path, **arrays) -> Path:
    """Write a compressed ``.npz`` of ``arrays`` atomically."""
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    return atomic_write_bytes(path, buf.getvalue())


def write_ply(path, vertices: np.ndarray, faces: np.ndarray, face_values: dict[str, np.ndarray] | None = None) -> Path:
    """A binary PLY with per-face scalar properties (e.g. energy density, J/m^2), atomically.

    vertices : (n, 3) m; faces : (m, 3) int; face_values : name -> (m,) float arrays.
    """
    import trimesh

    mesh = trimesh.Trimesh(np.asarray(vertices), np.asarray(faces), process=False)
    for k, v in (face_values or {}).items():
        mesh.face_attributes[k] = np.asarray(v, dtype=np.float64)
    return atomic_write_bytes(path, trimesh.exchange.ply.export_ply(mesh, include_attributes=True))


def prepare_output_folder(out, force: bool) -> Path:
    """Create the output folder ``out``; an existing non-empty one is replaced only with
    ``force`` (otherwise a KgarmentError names it)."""
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        if not force:
            raise KgarmentError(f"output folder {out} exists; use --force to replace it")
        shutil.rmtree(out) if out.is_dir() else out.unlink()
    out.mkdir(parents=True, exist_ok=True)
    return out
