"""Glue between the input stages (body, garment, clutches) and the simulator.

Builds the simulator's model and per-motion inputs from a :class:`~kgarment.body.Body`, a
:class:`~kgarment.garment.Garment` and clutch strips, parses activation patterns, and
writes equilibrium meshes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kgarment.errors import KgarmentError


def sim_motions(body, garment, motions=None) -> dict:
    """{motion name: kgarment.sim.Motion} for the garment's motions (or the given ones)."""
    from kgarment.sim import Motion

    out = {}
    attached = np.flatnonzero(garment.attached)
    for m in motions or garment.motion_names:
        out[m] = Motion.create(m, garment.vertices(m), body.vertices(m), body.normals(m), attached,
                               garment.attachment_targets(m), body.faces)
    return out


def parse_activation(text: str, n_clutches: int) -> tuple[float, ...]:
    """'on' (all 1), 'off' (all 0), or K comma-separated values in [0, 1] ('1,0,0.5')."""
    if text == "on":
        return (1.0,) * n_clutches
    if text == "off":
        return (0.0,) * n_clutches
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        vals = ()
    if len(vals) != n_clutches or not all(0.0 <= v <= 1.0 for v in vals):
        raise KgarmentError(f"clutch activation {text!r}: give on, off, or {n_clutches} comma-separated values in [0, 1]")
    return vals


def write_ply(path, vertices: np.ndarray, faces: np.ndarray, face_values: dict[str, np.ndarray] | None = None) -> Path:
    """Write a binary PLY with per-face scalar properties (e.g. energy density, J/m^2).

    vertices : (n, 3) m; faces : (m, 3); face_values : name -> (m,) float arrays.
    """
    import trimesh

    mesh = trimesh.Trimesh(np.asarray(vertices), np.asarray(faces), process=False)
    for k, v in (face_values or {}).items():
        mesh.face_attributes[k] = np.asarray(v, dtype=np.float64)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.ply")
    tmp.write_bytes(trimesh.exchange.ply.export_ply(mesh, include_attributes=True))
    tmp.replace(path)
    return path


def load_design(path, n_faces: int) -> np.ndarray:
    """A design (n_faces,) in [x_min, 1] from .npy / .npz ('design' array) / .txt, or a
    run folder ``RUN`` (its final design) / ``RUN@K`` (the design of iteration K)."""
    run, _, it = str(path).partition("@")
    if Path(run).is_dir():
        from kgarment.design.beso import X_MIN
        from kgarment.design.run import load_design_history

        hist = load_design_history(run)
        if it and not it.isdigit():
            raise KgarmentError(f"iteration {it!r} in {path!r} must be a number")
        k = int(it) if it else len(hist) - 1
        if not 0 <= k < len(hist):
            raise KgarmentError(f"{run} has iterations 0..{len(hist) - 1}; asked for {k}")
        if hist.shape[1] != n_faces:
            raise KgarmentError(f"the design in {run} has {hist.shape[1]} faces, the garment {n_faces}")
        return np.where(hist[k], 1.0, X_MIN)
    path = Path(path)
    if not path.is_file():
        raise KgarmentError(f"design file not found: {path}")
    try:
        if path.suffix == ".npz":
            with np.load(path) as z:
                d = z["design"] if "design" in z.files else z[z.files[0]]
        elif path.suffix == ".npy":
            d = np.load(path)
        else:
            d = np.loadtxt(path)
    except Exception as exc:
        raise KgarmentError(f"cannot read design {path}: {exc}") from None
    d = np.asarray(d, dtype=np.float64).reshape(-1)
    if d.shape != (n_faces,):
        raise KgarmentError(f"design {path} has {d.size} values, the garment has {n_faces} faces")
    if not np.all((d > 0) & (d <= 1)):
        raise KgarmentError(f"design {path}: values must lie in (0, 1]")
    return d
