"""A body given as mesh files sharing one topology: a rest mesh and one per motion.

For users who pose STAR/SMPL or scanned bodies elsewhere. Files are OBJ or PLY (anything
trimesh reads), in metres, Z up, facing -Y, with identical vertex order and faces.
An optional rig file (``.npz`` with ``bone_names`` (B,), ``bone_parents`` (B,),
``skin_indices`` (n, k), ``skin_weights`` (n, k), ``rest_joints`` (B, 3)) enables the
bone-region garment templates; without one, garments are given as face masks.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kgarment.body.model import Body
from kgarment.errors import KgarmentError

MESH_SUFFIXES = (".obj", ".ply", ".off", ".stl", ".glb")


def read_mesh(path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n, 3) float64 and faces (m, 3) int64 of a mesh file, vertex order kept."""
    import trimesh

    path = Path(path)
    if not path.is_file():
        raise KgarmentError(f"mesh file not found: {path}")
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise KgarmentError(f"unsupported mesh file {path.name}; use one of {', '.join(MESH_SUFFIXES)}")
    try:
        mesh = trimesh.load(path, process=False, force="mesh")
    except Exception as exc:  # trimesh raises many kinds
        raise KgarmentError(f"cannot read mesh {path}: {exc}") from None
    v = np.asarray(mesh.vertices, dtype=np.float64)
    f = np.asarray(mesh.faces, dtype=np.int64)
    if len(f) == 0 or f.shape[1] != 3:
        raise KgarmentError(f"mesh {path} has no triangles")
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        raise KgarmentError(f"mesh {path} has {int(bad.sum())} vertices with NaN or infinite coordinates "
                            f"(the first: vertex {int(np.flatnonzero(bad)[0])})")
    return v, f


def load_mesh_sequence(rest, motions: dict[str, str | Path], rig=None) -> Body:
    """A :class:`Body` from a rest mesh file and ``{motion name: mesh file}``."""
    v0, f0 = read_mesh(rest)
    posed = []
    for name, path in motions.items():
        v, f = read_mesh(path)
        if v.shape != v0.shape or f.shape != f0.shape or not np.array_equal(f, f0):
            raise KgarmentError(
                f"mesh for motion {name!r} ({Path(path).name}: {len(v)} vertices, {len(f)} faces) "
                f"does not share the rest mesh's topology ({len(v0)} vertices, {len(f0)} faces)"
            )
        posed.append(v)
    names: tuple[str, ...] = ()
    parents = np.zeros(0, dtype=np.int64)
    si = np.zeros((len(v0), 0), dtype=np.int64)
    sw = np.zeros((len(v0), 0))
    joints = np.zeros((0, 3))
    if rig is not None:
        rig = Path(rig)
        if not rig.is_file():
            raise KgarmentError(f"rig file not found: {rig}")
        try:
            with np.load(rig) as z:
                names = tuple(str(b) for b in z["bone_names"])
                parents, si, sw, joints = (z[k] for k in ("bone_parents", "skin_indices", "skin_weights", "rest_joints"))
        except KeyError as exc:
            raise KgarmentError(f"rig file {rig} lacks {exc}; needs bone_names, bone_parents, skin_indices, skin_weights, rest_joints") from None
        if si.shape[0] != len(v0):
            raise KgarmentError(f"rig file {rig} has weights for {si.shape[0]} vertices, the mesh has {len(v0)}")
    k = len(posed)
    return Body(
        rest_vertices=v0,
        faces=f0,
        bone_names=names,
        bone_parents=np.asarray(parents, dtype=np.int64),
        skin_indices=np.asarray(si, dtype=np.int64),
        skin_weights=np.asarray(sw, dtype=np.float64),
        rest_joints=np.asarray(joints, dtype=np.float64),
        motion_names=tuple(motions),
        posed_vertices=np.array(posed).reshape(k, len(v0), 3),
        posed_joints=np.full((k, len(names), 3), np.nan),
        source=f"mesh sequence {Path(rest).name}",
    )
