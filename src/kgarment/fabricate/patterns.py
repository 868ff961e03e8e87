"""From a cleaned design to flat patches: split, flatten, and cut seams where distortion is high.

Every edge-connected piece of reinforcement is flattened. While a piece's largest edge
length distortion exceeds ``max_distortion`` it is cut along a short seam and the pieces are
flattened again: first its holes are opened to the outer boundary (a ring around the arm
becomes a strip), then it is split in two along the shortest boundary-to-boundary path
through its most distorted triangle. Each original piece gets at most ``max_cuts`` cuts,
and no cut may leave a piece smaller than ``min_piece_area``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from kgarment.errors import KgarmentError
from kgarment.fabricate.flatten import METHODS, Flattening, flatten
from kgarment.fabricate.patches import PatchMesh, cut_patch, hole_seams, split_patches, through_seam

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class PatternOptions:
    """method : "arap" or "lscm"; max_distortion : edge strain |l2/l3 - 1| that asks for a
    seam; max_cuts : seams per original piece; min_piece_area : m^2 (a split must also leave
    every piece at least 5% of the area it splits);
    arap_iterations : local/global iterations."""

    method: str = "arap"
    max_distortion: float = 0.05
    max_cuts: int = 4
    min_piece_area: float = 2e-4
    arap_iterations: int = 50

    def __post_init__(self):
        if self.method not in METHODS:
            raise KgarmentError(f"flattening method {self.method!r}; allowed: {', '.join(METHODS)}")
        if not self.max_distortion > 0:
            raise KgarmentError(f"max_distortion = {self.max_distortion!r} must be > 0")
        if self.max_cuts < 0:
            raise KgarmentError(f"max_cuts = {self.max_cuts!r} must be >= 0")


@dataclass(frozen=True)
class Patch:
    """One flat piece of reinforcement.

    label : "P1", "P2", ... (largest first). mesh : its :class:`PatchMesh`.
    flat : its :class:`Flattening`. piece : index of the connected piece of the design it
    came from (before seams were cut).
    """

    label: str
    mesh: PatchMesh
    flat: Flattening
    piece: int

    def face_of(self, garment_face: int) -> int | None:
        """The local face for a garment face id, or None when the face is not on the patch."""
        hit = np.flatnonzero(self.mesh.garment_face == garment_face)
        return int(hit[0]) if len(hit) else None

    def map_bary(self, garment_face: int, bary: np.ndarray) -> np.ndarray | None:
        """(2,) flat position (metres, patch coordinates) of a point given by barycentric
        coordinates bary (3,) in a garment face; None when the face is not on the patch."""
        f = self.face_of(garment_face)
        if f is None:
            return None
        return np.asarray(bary, dtype=np.float64) @ self.flat.uv[self.mesh.faces[f]]


@dataclass(frozen=True)
class Seam:
    """A cut between or inside patches: label "S1", ...; garment_vertices (k,) the path in
    garment vertex ids; kind "hole" (opens a hole) or "split" (separates two patches)."""

    label: str
    garment_vertices: np.ndarray
    kind: str

    def length(self, garment_vertices: np.ndarray) -> float:
        """Rest length in metres given the garment's (n, 3) rest vertices."""
        p = garment_vertices[self.garment_vertices]
        return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())


@dataclass(frozen=True)
class PatternSet:
    """All patches (largest first) and the seams cut between them."""

    patches: tuple[Patch, ...]
    seams: tuple[Seam, ...]

    def locate(self, garment_face: int, bary: np.ndarray):
        """(patch index, (2,) flat position) of a garment surface point, or None."""
        for i, p in enumerate(self.patches):
            uv = p.map_bary(garment_face, bary)
            if uv is not None:
                return i, uv
        return None


def _flatten(p: PatchMesh, o: PatternOptions) -> Flattening:
    return flatten(p.vertices, p.faces, o.method, o.arap_iterations)


def _split_lines(p: PatchMesh, fl: Flattening, threshold: float) -> list[tuple[np.ndarray, np.ndarray | None]]:
    """Candidate 2D lines (point, direction or None = across) to split along: through the
    most distorted triangle and through the centre of the over-distorted region, each
    across the patch and towards its centre; across the patch through its centre."""
    cen = fl.uv[p.faces].mean(axis=1)
    w = p.face_areas()
    middle = (w[:, None] * cen).sum(0) / w.sum()
    strain = np.where(np.isfinite(fl.face_strain), fl.face_strain, 1e9)
    bad = strain > threshold
    pts = [cen[int(np.argmax(strain))]]
    if bad.any():
        pts.append((w[bad, None] * cen[bad]).sum(0) / w[bad].sum())
    lines = []
    for q in pts:
        lines.append((q, None))
        if np.linalg.norm(middle - q) > 1e-9:
            lines.append((q, middle - q))
    return lines + [(middle, None)]


def _next_cut(p: PatchMesh, fl: Flattening, o: PatternOptions):
    """(seams, kind, [(piece, flattening)]) for the next cut of an over-distorted patch: holes
    opened first, else the split (among a few candidate lines) whose pieces flatten with the
    least distortion; None when no cut is acceptable."""
    seams = hole_seams(p)
    if seams:
        return seams, "hole", [(q, _flatten(q, o)) for q in cut_patch(p, seams)]
    best, tried = None, set()
    for pt, d in _split_lines(p, fl, o.max_distortion):
        s = through_seam(p, fl.uv, pt, d)
        if s is None or len(s) < 2 or tuple(s) in tried:
            continue
        tried.add(tuple(s))
        pieces = cut_patch(p, [s])
        if len(pieces) < 2 or min(q.area() for q in pieces) < max(o.min_piece_area, 0.05 * p.area()):
            continue
        flat = [(q, _flatten(q, o)) for q in pieces]
        score = max(g.max_length_distortion for _, g in flat)
        if best is None or score < best[0]:
            best = (score, [s], "split", flat)
    return None if best is None else best[1:]


def make_patterns(garment_vertices: np.ndarray, garment_faces: np.ndarray, solid: np.ndarray,
                  options: PatternOptions = PatternOptions()) -> PatternSet:
    """Flat patches of the reinforced faces ``solid`` (m,) bool of a garment
    (rest vertices (n, 3) metres, faces (m, 3))."""
    done: list[tuple[int, PatchMesh, Flattening]] = []
    seams: list[tuple[np.ndarray, str]] = []
    for k, piece in enumerate(split_patches(garment_vertices, garment_faces, np.asarray(solid, bool))):
        todo, cuts = [(piece, _flatten(piece, options))], 0
        while todo:
            todo.sort(key=lambda t: t[1].max_length_distortion)
            p, fl = todo.pop()  # the most distorted piece first
            if fl.max_length_distortion <= options.max_distortion or cuts >= options.max_cuts:
                done += [(k, p, fl)] + [(k, q, g) for q, g in todo]
                break
            cut = _next_cut(p, fl, options)
            if cut is None:
                log.info("piece %d: distortion %.1f%% but no acceptable seam", k, 100 * fl.max_length_distortion)
                done.append((k, p, fl))
                continue
            paths, kind, pieces = cut
            cuts += 1
            seams += [(p.garment_vertex[s], kind) for s in paths]
            log.info("piece %d: distortion %.1f%% > %.1f%%, cut %d %s seam(s) -> %d piece(s)", k,
                     100 * fl.max_length_distortion, 100 * options.max_distortion, len(paths), kind, len(pieces))
            todo += pieces
    for k, _, fl in done:
        if fl.max_length_distortion > options.max_distortion:
            log.warning("piece %d keeps a patch with %.1f%% length distortion (> %.1f%%)", k,
                        100 * fl.max_length_distortion, 100 * options.max_distortion)
    done.sort(key=lambda t: -t[1].area())
    patches = tuple(Patch(f"P{i + 1}", p, fl, k) for i, (k, p, fl) in enumerate(done))
    return PatternSet(patches, tuple(Seam(f"S{i + 1}", np.asarray(s, np.int64), kind)
                                     for i, (s, kind) in enumerate(seams)))
