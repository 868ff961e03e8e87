"""The default body: Anny (PyPI ``anny``), posed by our motion library, cached on disk.

Anny's own first load builds its model cache (about 1 to 2 minutes, ``ANNY_CACHE_DIR``).
On top of that, kgarment caches what it generates (rest mesh, rig, posed meshes) in
``KGARMENT_CACHE_DIR`` (default ``~/.cache/kgarment``), keyed by the phenotype, the
resolved motion rotations and the Anny version, so a cached body loads without importing
Anny at all.
"""

from __future__ import annotations

import hashlib
import json
import logging
from dataclasses import asdict, dataclass
from importlib import metadata

import numpy as np

from kgarment.body.model import Body
from kgarment.body.motions import Motion, bone_rotations
from kgarment.errors import KgarmentError
from kgarment.io import atomic_save_npz, cache_dir

log = logging.getLogger(__name__)
CACHE_FORMAT = 1
PHENOTYPE_FIELDS = ("gender", "age", "muscle", "weight", "height", "proportions")


@dataclass(frozen=True)
class Phenotype:
    """Anny's phenotype parameters, each in [0, 1] (0.5 = the model's average).  ``gender``:
    0 male, 1 female (Anny's convention: its shape distribution reads gender <= 0.5 as boys)."""

    gender: float = 0.5
    age: float = 0.5
    muscle: float = 0.5
    weight: float = 0.5
    height: float = 0.5
    proportions: float = 0.5

    def __post_init__(self):
        for k, v in asdict(self).items():
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.0 <= float(v) <= 1.0:
                raise KgarmentError(f"phenotype {k} = {v!r} is outside [0, 1]")

    @classmethod
    def from_dict(cls, d: dict) -> "Phenotype":
        if not isinstance(d, dict):
            raise KgarmentError(f"[body] phenotype = {d!r} must be a table {{{' = 0.5, '.join(PHENOTYPE_FIELDS)} = 0.5}}")
        bad = set(d) - set(PHENOTYPE_FIELDS)
        if bad:
            raise KgarmentError(f"unknown phenotype parameter {sorted(bad)[0]!r}; valid: {', '.join(PHENOTYPE_FIELDS)}")
        return cls(**{k: float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else v
                      for k, v in d.items()})


def _key(obj) -> str:
    return hashlib.sha256(json.dumps(obj, sort_keys=True).encode()).hexdigest()[:16]


def _anny_version() -> str:
    try:
        return metadata.version("anny")
    except metadata.PackageNotFoundError:  # pragma: no cover
        return "unknown"


def _quiet_warp() -> None:
    """Keep NVIDIA Warp (which Anny uses) from printing its start-up banner on stdout unless
    kgarment logs at INFO or more (without -q)."""
    try:
        import warp
    except ImportError:  # pragma: no cover - anny without warp
        return
    warp.config.quiet = not log.isEnabledFor(logging.INFO)


class _AnnyModel:
    """Loads Anny lazily (only on a cache miss)."""

    def __init__(self, phenotype: Phenotype):
        self.phenotype = phenotype
        self._model = None

    def model(self):
        if self._model is None:
            _quiet_warp()
            import anny  # deferred: importing and building Anny is the slow part
            import torch

            log.info("loading Anny (the very first load builds Anny's cache, ~2 minutes)")
            torch.set_default_dtype(torch.float64)
            self._model = anny.Anny()
        return self._model

    def forward(self, rotations: dict[str, np.ndarray] | None):
        import torch

        m = self.model()
        pose = None
        if rotations:
            pose = {}
            for bone, R in rotations.items():
                T = torch.eye(4, dtype=m.dtype)
                T[:3, :3] = torch.as_tensor(R, dtype=m.dtype)
                pose[bone] = T[None]
        with torch.no_grad():
            out = m(pose_parameters=pose, phenotype_kwargs=asdict(self.phenotype))
        verts = out["vertices"][0].cpu().numpy().astype(np.float64)
        joints = out["bone_poses"][0, :, :3, 3].cpu().numpy().astype(np.float64)
        return verts, joints


def _largest_component(vertices: np.ndarray, faces: np.ndarray):
    """Keep the largest connected component (Anny ships eyes as separate shells)."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    n = len(vertices)
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    g = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n))
    _, labels = connected_components(g, directed=False)
    big = np.argmax(np.bincount(labels[faces[:, 0]]))
    keep_v = labels == big
    remap = -np.ones(n, dtype=np.int64)
    remap[keep_v] = np.arange(keep_v.sum())
    keep_f = keep_v[faces[:, 0]]
    return keep_v, remap[faces[keep_f]]


def _rest_data(phenotype: Phenotype, model: _AnnyModel) -> dict:
    folder = cache_dir() / f"anny-{_anny_version()}-v{CACHE_FORMAT}" / _key(asdict(phenotype))
    path = folder / "rest.npz"
    if path.exists():
        with np.load(path) as z:
            return {k: z[k] for k in z.files}
    log.info("building the rest body (phenotype %s)", asdict(phenotype))
    m = model.model()
    verts, joints = model.forward(None)
    faces = m.get_triangular_faces().cpu().numpy().astype(np.int64)
    keep_v, faces = _largest_component(verts, faces)
    data = dict(
        rest_vertices=verts[keep_v],
        faces=faces,
        keep_vertices=keep_v,
        bone_names=np.array(m.bone_labels),
        bone_parents=np.asarray(m.bone_parents, dtype=np.int64),
        skin_indices=m.vertex_bone_indices.cpu().numpy().astype(np.int64)[keep_v],
        skin_weights=m.vertex_bone_weights.cpu().numpy().astype(np.float64)[keep_v],
        rest_joints=joints,
    )
    atomic_save_npz(path, **data)
    return data


def anny_rig(phenotype: Phenotype | None = None) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
    """The rig of the Anny body with ``phenotype``: bone names (B,), parents (B,) int, rest joints (B, 3) m.

    Read from the rest body's cache (built on a miss, as :func:`load_anny_body` does).
    """
    phenotype = phenotype or Phenotype()
    rest = _rest_data(phenotype, _AnnyModel(phenotype))
    return tuple(str(b) for b in rest["bone_names"]), rest["bone_parents"], rest["rest_joints"]


def load_anny_body(motions: list[Motion], phenotype: Phenotype | None = None) -> Body:
    """The Anny body with the given phenotype, posed in each motion's target pose.

    Every generated mesh is cached; Anny is imported only on a cache miss.
    """
    phenotype = phenotype or Phenotype()
    model = _AnnyModel(phenotype)
    rest = _rest_data(phenotype, model)
    names = tuple(str(b) for b in rest["bone_names"])
    parents, joints0 = rest["bone_parents"], rest["rest_joints"]
    keep = rest["keep_vertices"]
    folder = cache_dir() / f"anny-{_anny_version()}-v{CACHE_FORMAT}" / _key(asdict(phenotype))
    posed_v, posed_j = [], []
    for motion in motions:
        rots = bone_rotations(motion.target, names, parents, joints0)
        key = _key({b: np.round(R, 12).tolist() for b, R in sorted(rots.items())})
        path = folder / f"pose-{key}.npz"
        if path.exists():
            with np.load(path) as z:
                v, j = z["vertices"], z["joints"]
        else:
            log.info("posing the body: %s", motion.name)
            v, j = model.forward(rots)
            v = v[keep]
            atomic_save_npz(path, vertices=v, joints=j)
        posed_v.append(v)
        posed_j.append(j)
    n = len(rest["rest_vertices"])
    return Body(
        rest_vertices=rest["rest_vertices"],
        faces=rest["faces"],
        bone_names=names,
        bone_parents=parents,
        skin_indices=rest["skin_indices"],
        skin_weights=rest["skin_weights"],
        rest_joints=joints0,
        motion_names=tuple(m.name for m in motions),
        posed_vertices=np.array(posed_v).reshape(len(motions), n, 3),
        posed_joints=np.array(posed_j).reshape(len(motions), len(names), 3),
        source=f"anny {_anny_version()} {asdict(phenotype)}",
    )
