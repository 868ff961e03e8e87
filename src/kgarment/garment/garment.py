"""The :class:`Garment`: a region of the body surface, subdivided, with attachment rings.

A garment vertex is a fixed linear combination of body vertices (the sparse
``embedding``), so its skin-tight place on any posed body is ``embedding @ posed``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from kgarment.body.model import Body
from kgarment.errors import KgarmentError, unknown
from kgarment.garment.templates import GarmentTemplate, builtin_templates
from kgarment.garment.topology import (
    boundary_loops,
    check_manifold,
    clean_face_mask,
    midpoint_subdivide,
    triangle_areas,
)

ALIASES = {"arm_sleeve": "arm_sleeve.right", "knee_sleeve": "knee_sleeve.right"}
MIN_GARMENT_FACES = 20  # the fewest body faces a garment mask may select (a garment is a piece of cloth)


@dataclass(frozen=True)
class Garment:
    """A garment mesh on a body.

    Attributes
    ----------
    name : str
    rest_vertices : (n, 3) float64, metres, on the rest body.
    faces : (m, 3) int64.
    embedding : (n, nb) sparse CSR, rows sum to 1: garment = embedding @ body vertices.
    body_face : (m,) int64, the body face each garment face was cut from.
    attached : (m,) bool, faces glued to the body (attachment rings).
    loops : dict name -> (k,) int64 ordered boundary vertex loop, named after the cut
        that made it ("hem", "cuff.L", ...) or "opening<i>" for free openings.
    subdivision : int, levels of midpoint subdivision applied to the body's faces.
    initial : (K, n, 3) float64, the skin-tight garment on each posed body (motion order
        of the body).
    motion_names : tuple of K str.
    """

    name: str
    rest_vertices: np.ndarray
    faces: np.ndarray
    embedding: sp.csr_matrix
    body_face: np.ndarray
    attached: np.ndarray
    loops: dict = field(default_factory=dict)
    subdivision: int = 0
    initial: np.ndarray | None = None
    motion_names: tuple[str, ...] = ()

    @property
    def n_vertices(self) -> int:
        return int(self.rest_vertices.shape[0])

    @property
    def n_faces(self) -> int:
        return int(self.faces.shape[0])

    def face_areas(self, vertices: np.ndarray | None = None) -> np.ndarray:
        """(m,) triangle areas in m^2 (rest shape unless ``vertices`` (n, 3) is given)."""
        return triangle_areas(self.rest_vertices if vertices is None else vertices, self.faces)

    def vertices(self, motion: str = "rest") -> np.ndarray:
        """(n, 3) skin-tight garment in the target pose of ``motion``."""
        if motion == "rest":
            return self.rest_vertices
        if motion not in self.motion_names:
            raise unknown("motion", motion, ("rest",) + self.motion_names)
        return self.initial[self.motion_names.index(motion)]

    def attachment_targets(self, motion: str) -> np.ndarray:
        """(a, 3) centroids of the attached faces on the posed body (skin-tight)."""
        return self.vertices(motion)[self.faces[self.attached]].mean(axis=1)


def _cut_mask(body: Body, template: GarmentTemplate) -> np.ndarray:
    for b in template.bones:
        body.bone_index(b)
    fb = body.face_bone()
    names = np.array(body.bone_names)
    face_bone_name = names[fb]
    mask = np.isin(face_bone_name, template.bones)
    cent = body.rest_vertices[body.faces].mean(axis=1)
    J = body.rest_joints
    for cut in template.cuts:
        a, b = J[body.bone_index(cut.joint_a)], J[body.bone_index(cut.joint_b)]
        p, n = a + cut.t * (b - a), b - a
        s = (cent - p) @ n
        drop = (s > 0) if cut.keep == "a" else (s < 0)
        mask &= ~(drop & np.isin(face_bone_name, cut.applies_to))
    return mask


def _name_loops(vertices, loops, body: Body | None, template: GarmentTemplate | None):
    named, k = {}, 0
    for loop in loops:
        best, best_d = None, 0.02  # a loop within 2 cm of a cut plane belongs to it
        if template is not None and body is not None:
            pts = vertices[loop]
            J = body.rest_joints
            for cut in template.cuts:
                a, b = J[body.bone_index(cut.joint_a)], J[body.bone_index(cut.joint_b)]
                n = (b - a) / np.linalg.norm(b - a)
                d = np.abs((pts - (a + cut.t * (b - a))) @ n).mean()
                if d < best_d and cut.name not in named:
                    best, best_d = cut.name, d
        if best is None:
            best, k = f"opening{k}", k + 1
        named[best] = loop
    return named


def garment_from_mask(body: Body, mask: np.ndarray, name: str = "garment", subdivision: int = 1,
                      attach: tuple[str, ...] = (), template: GarmentTemplate | None = None,
                      clean: bool = True) -> Garment:
    """A garment from a face mask (nb_faces,) bool on the body.

    attach : names of boundary loops to glue ("hem", "opening0", ... or "all").
    """
    mask = np.asarray(mask, dtype=bool)
    if mask.shape != (len(body.faces),):
        raise KgarmentError(f"face mask has {mask.size} entries, the body has {len(body.faces)} faces")
    if mask.sum() < MIN_GARMENT_FACES:
        raise KgarmentError(f"garment {name!r} selects {int(mask.sum())} faces of the body; a garment needs at least "
                            f"{MIN_GARMENT_FACES} connected faces")
    if clean:
        mask = clean_face_mask(body.faces, mask)
    if mask.sum() < MIN_GARMENT_FACES:
        raise KgarmentError(f"garment {name!r} keeps {int(mask.sum())} faces once cleaned (its largest connected "
                            f"piece); a garment needs at least {MIN_GARMENT_FACES}")
    if subdivision not in (0, 1, 2, 3):
        raise KgarmentError(f"subdivision = {subdivision!r}; allowed: 0, 1, 2, 3")
    bf = np.flatnonzero(mask)
    used, faces = np.unique(body.faces[bf], return_inverse=True)
    faces = faces.reshape(-1, 3).astype(np.int64)
    E = sp.csr_matrix((np.ones(len(used)), (np.arange(len(used)), used)), shape=(len(used), body.n_vertices))
    body_face = bf
    for _ in range(subdivision):
        faces, S = midpoint_subdivide(faces, E.shape[0])
        E = (S @ E).tocsr()
        body_face = np.repeat(body_face[None], 4, axis=0).reshape(-1)  # 4 children, in blocks
    rest = E @ body.rest_vertices
    check_manifold(rest, faces, f"garment {name!r}")
    loops = _name_loops(rest, boundary_loops(faces), body, template)
    if "all" in attach:
        attach = tuple(loops)
    missing = [a for a in attach if a not in loops]
    if missing:
        raise unknown("attachment loop", missing[0], loops)
    ring = np.zeros(len(rest), bool)
    for a in attach:
        ring[loops[a]] = True
    attached = ring[faces].any(axis=1)
    initial = np.stack([E @ v for v in body.posed_vertices]) if len(body.motion_names) else np.zeros((0, len(rest), 3))
    return Garment(name, rest, faces, E, body_face, attached, loops, subdivision, initial, body.motion_names)


def template_names() -> list[str]:
    return list(builtin_templates()) + list(ALIASES)


def make_garment(body: Body, template: str, subdivision: int = 1) -> Garment:
    """A built-in garment template on ``body`` at the given subdivision level."""
    templates = builtin_templates()
    key = ALIASES.get(template, template)
    if key not in templates:
        raise unknown("garment", template, template_names())
    t = templates[key]
    return garment_from_mask(body, _cut_mask(body, t), key, subdivision, t.attach, t)


def load_face_mask(path, n_faces: int) -> np.ndarray:
    """A face mask from a file: ``.npy``/``.npz`` (bool (m,) or face indices) or ``.txt``
    (one face index per line). Returns (n_faces,) bool."""
    from pathlib import Path

    path = Path(path)
    if path.is_dir():
        raise KgarmentError(f"face mask {path} is a folder, not a file (.npy, .npz or .txt)")
    if not path.is_file():
        raise KgarmentError(f"face mask file not found: {path}")
    try:
        if path.suffix == ".npy":
            a = np.load(path)
        elif path.suffix == ".npz":
            with np.load(path) as z:
                if not z.files:
                    raise KgarmentError(f"face mask {path} holds no array; save the mask as one array")
                a = z[z.files[0]]
        else:
            if not path.read_text(errors="replace").strip():
                raise KgarmentError(f"face mask {path} is empty; it must list the garment's body faces")
            a = np.loadtxt(path, dtype=np.int64, ndmin=1)
    except KgarmentError:
        raise
    except Exception as exc:
        raise KgarmentError(f"cannot read face mask {path}: {exc}") from None
    if a.dtype == bool:
        if a.shape != (n_faces,):
            raise KgarmentError(f"face mask {path} has {a.size} entries, the body has {n_faces} faces")
        return a
    if not np.issubdtype(a.dtype, np.number) or (np.issubdtype(a.dtype, np.floating)
                                                 and not np.all(np.isfinite(a) & (a == np.round(a)))):
        raise KgarmentError(f"face mask {path} must hold face indices (integers) or one boolean per body face")
    a = np.asarray(a, dtype=np.int64).reshape(-1)
    if a.size and (a.min() < 0 or a.max() >= n_faces):
        raise KgarmentError(f"face mask {path} has face indices outside [0, {n_faces - 1}]")
    m = np.zeros(n_faces, bool)
    m[a] = True
    return m
