"""The cleaned design in 3D with colours: GLB (a scene), OBJ and PLY (one mesh each).

Garment faces are coloured by patch (soft cloth light grey), clutch strips dark red, drawn
1 mm outside the garment so viewers do not mix the two surfaces. Coordinates are metres,
as everywhere in kgarment (Z up, the body faces -Y). The PLY keeps exact per-face colours
and a per-face ``patch`` property (-1 soft cloth, -2 clutch, else the patch index); the OBJ
and GLB carry the colours as vertex colours of an unmerged mesh, so faces stay crisp.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

SOFT_RGBA = (225, 228, 235, 255)
CLUTCH_RGBA = (150, 20, 30, 255)
CLUTCH_LIFT = 0.001  # metres


def patch_colors(n: int) -> np.ndarray:
    """(n, 4) uint8 distinct colours for n patches."""
    import matplotlib

    cmap = matplotlib.colormaps["tab10"]
    return (np.array([cmap(i % 10) for i in range(n)]) * 255).astype(np.uint8).reshape(-1, 4)


def face_patch_index(n_faces: int, patterns) -> np.ndarray:
    """(m,) int: the patch index of every garment face, -1 for soft cloth."""
    out = np.full(n_faces, -1, np.int64)
    for i, p in enumerate(patterns.patches):
        out[p.mesh.garment_face] = i
    return out


def _clutch_mesh(strips, vertices, faces):
    """(vertices (k, 3), faces (j, 3)) of all clutch strips, lifted off the garment."""
    tri = vertices[faces]
    nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True).clip(1e-300)
    vs, fs, off = [], [], 0
    for c in strips:
        vs.append(c.bound_positions(vertices, faces) + CLUTCH_LIFT * nrm[c.bind_face])
        fs.append(np.asarray(c.faces) + off)
        off += len(c.vertices)
    if not vs:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    return np.concatenate(vs), np.concatenate(fs)


def design_meshes(vertices: np.ndarray, faces: np.ndarray, patterns, strips):
    """(garment trimesh, clutch trimesh or None), coloured. vertices (n, 3) m, faces (m, 3)."""
    import trimesh

    idx = face_patch_index(len(faces), patterns)
    cols = np.tile(np.array(SOFT_RGBA, np.uint8), (len(faces), 1))
    pc = patch_colors(len(patterns.patches))
    cols[idx >= 0] = pc[idx[idx >= 0]]
    g = trimesh.Trimesh(vertices, faces, process=False, face_colors=cols)
    g.face_attributes["patch"] = idx.astype(np.float64)
    cv, cf = _clutch_mesh(strips, vertices, faces)
    c = None
    if len(cf):
        c = trimesh.Trimesh(cv, cf, process=False, face_colors=np.tile(np.array(CLUTCH_RGBA, np.uint8), (len(cf), 1)))
        c.face_attributes["patch"] = np.full(len(cf), -2.0)
    return g, c


def write_3d(vertices: np.ndarray, faces: np.ndarray, patterns, strips, stem) -> list[Path]:
    """Write ``stem``.glb, .obj and .ply of the garment (vertices (n, 3) metres, faces
    (m, 3)) coloured by ``patterns`` and its clutch ``strips``. Returns the paths."""
    import trimesh

    g, c = design_meshes(vertices, faces, patterns, strips)
    both = g if c is None else trimesh.util.concatenate([g, c])
    both.face_attributes["patch"] = np.concatenate([g.face_attributes["patch"]]
                                                    + ([] if c is None else [c.face_attributes["patch"]]))
    stem = Path(stem)
    ply = stem.with_suffix(".ply")
    ply.write_bytes(trimesh.exchange.ply.export_ply(both, include_attributes=True))

    def crisp(m):
        u = m.copy()
        u.face_attributes = {}
        u.unmerge_vertices()
        u.visual = trimesh.visual.ColorVisuals(u, vertex_colors=np.repeat(m.visual.face_colors, 3, axis=0))
        return u

    obj = stem.with_suffix(".obj")
    obj.write_text(trimesh.exchange.obj.export_obj(crisp(both), include_color=True, include_normals=False))
    scene = trimesh.Scene()
    scene.add_geometry(crisp(g), node_name="garment", geom_name="garment")
    if c is not None:
        scene.add_geometry(crisp(c), node_name="clutches", geom_name="clutches")
    glb = stem.with_suffix(".glb")
    glb.write_bytes(scene.export(file_type="glb"))
    return [glb, obj, ply]
