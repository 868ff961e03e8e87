"""Named landmarks on the rest body surface, for placing clutches by name.

A landmark is found by casting a ray from a point on the skeleton (a joint, or a point
between two joints) outwards and taking the first hit on the body surface. Sided
landmarks come as ``name.L`` / ``name.R`` and the aliases ``name.left`` / ``name.right``.
"""

from __future__ import annotations

import numpy as np

from kgarment.body.model import Body
from kgarment.errors import KgarmentError

# name -> (joint a, joint b, t along a->b, ray direction: a 3-vector or "elbow_out"/"elbow_in")
_CENTRAL = {
    "upper_back": ("spine01", "neck01", 0.1, (0.0, 1.0, 0.0)),
    "mid_back": ("spine02", "spine01", 0.0, (0.0, 1.0, 0.0)),
    "lower_back": ("spine03", "spine02", 0.0, (0.0, 1.0, 0.0)),
    "chest": ("spine01", "neck01", 0.1, (0.0, -1.0, 0.0)),
    "belly": ("spine03", "spine02", 0.0, (0.0, -1.0, 0.0)),
}
_SIDED = {
    "shoulder_top": ("shoulder01", "upperarm01", 0.6, (0.0, 0.0, 1.0)),
    "elbow_outer": ("lowerarm01", "wrist", 0.0, "elbow_out"),
    "elbow_inner": ("lowerarm01", "wrist", 0.0, "elbow_in"),
    "forearm_inner": ("lowerarm01", "wrist", 0.35, "elbow_in"),
    "upperarm_back": ("upperarm01", "lowerarm01", 0.5, (0.0, 1.0, 0.0)),
    "knee_front": ("lowerleg01", "foot", 0.0, (0.0, -1.0, 0.0)),
    "knee_back": ("lowerleg01", "foot", 0.0, (0.0, 1.0, 0.0)),
    "thigh_front": ("upperleg01", "lowerleg01", 0.5, (0.0, -1.0, 0.0)),
}


def landmark_names() -> list[str]:
    names = list(_CENTRAL)
    for n in _SIDED:
        names += [f"{n}.L", f"{n}.R", f"{n}.left", f"{n}.right"]
    return names


def _elbow_bisector(J, names, side):
    s = J[names.index(f"upperarm02.{side}")]
    e = J[names.index(f"lowerarm01.{side}")]
    w = J[names.index(f"wrist.{side}")]
    u = (s - e) / np.linalg.norm(s - e)
    v = (w - e) / np.linalg.norm(w - e)
    b = u + v  # points into the concave (inner) side of the bent elbow
    return b / np.linalg.norm(b)


def ray_triangles(origin: np.ndarray, direction: np.ndarray, triangles: np.ndarray, eps: float = 1e-14,
                  tol: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Moller-Trumbore intersection of one ray with every triangle (both sides count).

    origin, direction : (3,); triangles : (m, 3, 3) metres; eps : smallest |determinant|
    (rays parallel to a triangle miss it); tol : slack on the barycentric bounds.
    Returns t (m,) ray parameters (distances for a unit direction), u, v (m,) barycentric
    coordinates of vertices 1 and 2, and hit (m,) bool (in the triangle, t > 0).
    """
    e1 = triangles[:, 1] - triangles[:, 0]
    e2 = triangles[:, 2] - triangles[:, 0]
    p = np.cross(direction, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > eps
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = origin - triangles[:, 0]
    u = np.einsum("ij,ij->i", s, p) * inv
    q = np.cross(s, e1)
    v = (q @ direction) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    hit = ok & (u >= -tol) & (v >= -tol) & (u + v <= 1 + tol) & (t > 0)
    return t, u, v, hit


def first_hit(origin: np.ndarray, direction: np.ndarray, triangles: np.ndarray) -> float:
    """Distance along a ray to the nearest triangle it hits, inf if none.

    origin, direction : (3,); triangles : (m, 3, 3) metres.
    """
    t, _, _, hit = ray_triangles(origin, direction, triangles)
    return float(t[hit].min()) if hit.any() else float("inf")


def body_landmarks(body: Body) -> dict[str, np.ndarray]:
    """All landmarks as (3,) points on the rest body surface (metres)."""
    if not body.rigged:
        raise KgarmentError("landmarks need a rigged body; give clutch starts as points or (face, bary)")
    names = list(body.bone_names)
    J = body.rest_joints
    entries = {}
    for n, spec in _CENTRAL.items():
        entries[n] = spec
    for n, (a, b, t, d) in _SIDED.items():
        for side in "LR":
            entries[f"{n}.{side}"] = (f"{a}.{side}", f"{b}.{side}", t, (d, side))
    origins, dirs, keys = [], [], []
    for n, (a, b, t, d) in entries.items():
        pa, pb = J[names.index(a)], J[names.index(b)]
        o = pa + t * (pb - pa)
        if isinstance(d, tuple) and len(d) == 2 and isinstance(d[0], str):
            kind, side = d
            bis = _elbow_bisector(J, names, side)
            d = -bis if kind == "elbow_out" else bis
        elif isinstance(d, tuple) and len(d) == 2:
            vec, side = d
            d = np.array(vec, dtype=float) * (np.array([-1.0, 1.0, 1.0]) if side == "R" else 1.0)
        origins.append(o)
        dirs.append(np.asarray(d, dtype=float) / np.linalg.norm(d))
        keys.append(n)
    origins, dirs = np.array(origins), np.array(dirs)
    tri = body.rest_vertices[body.faces]
    out = {}
    for i, key in enumerate(keys):
        t = first_hit(origins[i], dirs[i], tri)
        if not np.isfinite(t):
            raise KgarmentError(f"landmark {key!r}: no body surface found from the skeleton")
        out[key] = origins[i] + t * dirs[i]
    for key in list(out):
        if key.endswith(".L") or key.endswith(".R"):
            out[key[:-2] + (".left" if key.endswith(".L") else ".right")] = out[key]
    return out
