"""What the page draws: poses between rest and target, and per-face colours.

Pure functions of arrays, so the drawing logic is tested without a browser.
Colour modes: "design" (reinforced / soft, attachments outlined in orange),
"attachments", "strain" (largest principal stretch - 1 against rest), "energy density"
(J/m^2, from a simulation), "compare" (A only / B only / both / neither) and "run"
(an iteration of an open run).
"""

from __future__ import annotations

import matplotlib
import numpy as np
import trimesh

from kgarment.body import vertex_normals

MODES = ("design", "attachments", "strain", "energy density", "compare", "run")
SKIN = (214, 194, 178)
SOFT = (204, 217, 242)
REINFORCED = (38, 51, 115)
ATTACHED = (235, 89, 31)
ONLY_A = (38, 51, 115)
ONLY_B = (214, 60, 60)
BOTH = (120, 40, 140)
CLUTCH_ON = (242, 199, 26)
CLUTCH_OFF = (140, 128, 89)
SELECTED = (20, 200, 90)


def interpolate(rest: np.ndarray, target: np.ndarray, t: float) -> np.ndarray:
    """(n, 3) linear blend of rest (n, 3) and target (n, 3) positions, t in [0, 1]."""
    t = float(np.clip(t, 0.0, 1.0))
    return (1.0 - t) * np.asarray(rest) + t * np.asarray(target)


def face_strain(rest: np.ndarray, faces: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(m,) largest principal stretch minus 1 of each triangle from rest (n, 3) to x (n, 3)
    (0: unstretched, 0.1: 10 % longer along the most stretched direction)."""
    R, X = np.asarray(rest)[faces], np.asarray(x)[faces]
    e1, e2 = R[:, 1] - R[:, 0], R[:, 2] - R[:, 0]
    u = e1 / np.maximum(np.linalg.norm(e1, axis=1, keepdims=True), 1e-300)
    n = np.cross(e1, e2)
    v = np.cross(n, u)
    v /= np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-300)
    Dm = np.stack([np.stack([np.einsum("ij,ij->i", e1, u), np.einsum("ij,ij->i", e2, u)], -1),
                   np.stack([np.einsum("ij,ij->i", e1, v), np.einsum("ij,ij->i", e2, v)], -1)], 1)  # (m, 2, 2)
    Ds = np.stack([X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]], axis=-1)  # (m, 3, 2)
    det = Dm[:, 0, 0] * Dm[:, 1, 1] - Dm[:, 0, 1] * Dm[:, 1, 0]
    ok = np.abs(det) > 1e-300
    inv = np.zeros_like(Dm)
    inv[ok] = np.linalg.inv(Dm[ok])
    Fd = Ds @ inv  # (m, 3, 2)
    C = np.einsum("mki,mkj->mij", Fd, Fd)
    lam = np.linalg.eigvalsh(C)[:, -1]
    return np.where(ok, np.sqrt(np.maximum(lam, 0.0)) - 1.0, 0.0)


def scalar_colors(values: np.ndarray, vmin: float | None = None, vmax: float | None = None,
                  cmap: str = "viridis") -> tuple[np.ndarray, float, float]:
    """((m, 3) uint8 colours, vmin, vmax) of per-face values (m,) (range: 1st-99th percentile)."""
    v = np.asarray(values, dtype=np.float64)
    finite = v[np.isfinite(v)]
    lo = float(np.percentile(finite, 1)) if vmin is None and finite.size else (vmin or 0.0)
    hi = float(np.percentile(finite, 99)) if vmax is None and finite.size else (vmax or 1.0)
    if hi <= lo:
        hi = lo + 1e-12
    t = np.clip((np.nan_to_num(v, nan=lo) - lo) / (hi - lo), 0.0, 1.0)
    rgb = (matplotlib.colormaps[cmap](t)[:, :3] * 255).round().astype(np.uint8)
    return rgb, lo, hi


def design_colors(design: np.ndarray, attached: np.ndarray | None = None) -> np.ndarray:
    """(m, 3) uint8: dark for reinforced, light for soft cloth; attached soft faces orange,
    attached reinforced faces a darker orange."""
    d = np.asarray(design, bool)
    out = np.where(d[:, None], REINFORCED, SOFT).astype(np.uint8)
    if attached is not None:
        a = np.asarray(attached, bool)
        out[a & ~d] = ATTACHED
        out[a & d] = (150, 60, 20)
    return out


def attachment_colors(attached: np.ndarray) -> np.ndarray:
    """(m, 3) uint8: attached faces orange, the rest light."""
    return np.where(np.asarray(attached, bool)[:, None], ATTACHED, SOFT).astype(np.uint8)


def compare_colors(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(m, 3) uint8 diff of two designs (m,) bool: A only, B only, both, neither."""
    a, b = np.asarray(a, bool), np.asarray(b, bool)
    out = np.tile(np.array(SOFT, np.uint8), (len(a), 1))
    out[a & ~b] = ONLY_A
    out[~a & b] = ONLY_B
    out[a & b] = BOTH
    return out


def swatch(rgb) -> str:
    """A small coloured square for legends (HTML inside markdown)."""
    r, g, b = (int(c) for c in rgb)
    return f'<span style="color:rgb({r},{g},{b})">&#9632;</span>'


def legend(mode: str, lo: float | None = None, hi: float | None = None, note: str = "") -> str:
    """Markdown legend for a colour mode (lo, hi: the range of scalar modes)."""
    if mode == "design":
        text = f"{swatch(REINFORCED)} reinforced {swatch(SOFT)} soft {swatch(ATTACHED)} attached"
    elif mode == "attachments":
        text = f"{swatch(ATTACHED)} attached {swatch(SOFT)} free"
    elif mode == "compare":
        text = f"{swatch(ONLY_A)} A only {swatch(ONLY_B)} B only {swatch(BOTH)} both {swatch(SOFT)} neither"
    elif mode == "run":
        text = f"{swatch(REINFORCED)} reinforced {swatch(SOFT)} soft (run iteration)"
    elif mode == "strain":
        text = f"largest principal stretch - 1: {lo:.3f} (dark) to {hi:.3f} (yellow)"
    else:
        text = f"energy density: {lo:.3g} (dark) to {hi:.3g} J/m² (yellow)"
    return text + (f"  \n{note}" if note else "")


def unwelded(vertices: np.ndarray, faces: np.ndarray, colors: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(3m, 3) vertices, (m, 3) faces, (3m, 3) uint8 vertex colours: every face gets its own
    three vertices, so per-face colours survive as vertex colours (flat per face)."""
    F = np.asarray(faces)
    v = np.asarray(vertices)[F].reshape(-1, 3)
    f = np.arange(3 * len(F)).reshape(-1, 3)
    return v, f, np.repeat(np.asarray(colors, np.uint8), 3, axis=0)


def glb_bytes(vertices: np.ndarray, faces: np.ndarray, colors: np.ndarray) -> bytes:
    """A GLB of a mesh (n, 3)/(m, 3) with per-face colours (m, 3) uint8 (for viser)."""
    v, f, c = unwelded(vertices, faces, colors)
    mesh = trimesh.Trimesh(v, f, process=False)
    mesh.visual = trimesh.visual.ColorVisuals(mesh, vertex_colors=np.concatenate(
        [c, np.full((len(c), 1), 255, np.uint8)], axis=1))
    return mesh.export(file_type="glb")


def offset_along_normals(vertices: np.ndarray, faces: np.ndarray, distance: float) -> np.ndarray:
    """(n, 3) vertices pushed ``distance`` metres along their area-weighted normals (to draw
    the garment and clutches just above the skin)."""
    return np.asarray(vertices) + distance * vertex_normals(np.asarray(vertices), np.asarray(faces))
