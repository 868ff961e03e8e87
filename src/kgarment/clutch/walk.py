"""Straight-ahead walks on a triangle mesh (geodesic tracing by unfolding).

From a start point and a tangent direction, go straight within the current triangle
until an edge is hit, rotate the direction about that edge into the next triangle
(unfold), and repeat until the requested length is used up. Every edge crossing is
recorded.

Special cases
-------------
* Through a vertex: the path leaves so that the surface angle on its left equals the
  angle on its right (Polthier & Schmies' *straightest* geodesic); on a flat vertex
  (angle sum 2 pi) this is the straight continuation. At a boundary vertex the path goes
  on at an angle of pi from where it came in, if that lies on the garment.
* Along an edge: a direction within ``_EPS_DIR`` (cosine) of an edge is walked along it.
* Start on a vertex: the direction is placed in the one-ring by its angle in the start
  face, unfolded around the vertex.
* Boundary: :class:`ClutchError` saying how far the walk got, or with ``clip=True`` the
  walk stops there and ``SurfacePath.complete`` is False.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from kgarment.clutch.errors import ClutchError
from kgarment.clutch.topology import MeshTopology

_EPS_DIR = 1e-10  # |cos| below which a direction counts as parallel to an edge
_SNAP = 1e-10  # barycentric coordinate below which an exit point snaps to a vertex
_MAX_FAN = 512


@dataclass(frozen=True)
class SurfacePath:
    """A walked path: the start, every edge (or vertex) crossing, and the end.

    Attributes
    ----------
    faces : (k,) int64
        Face of each point: the face the path goes on in (the last face for the end).
    bary : (k, 3) float64
        Barycentric coordinates of each point in ``faces``.
    points : (k, 3) float64
        3D positions, metres. Consecutive points lie in one face, so the path is the
        polyline through them.
    directions : (k, 3) float64
        Unit tangent of the path at each point, in the plane of ``faces``.
    arclength : (k,) float64
        Distance along the path from the start, metres.
    length : float
        Walked length, metres (``requested`` unless the walk was clipped).
    requested : float
        Requested length, metres.
    complete : bool
        False when the walk stopped at the mesh boundary (``clip=True``).
    """

    faces: np.ndarray
    bary: np.ndarray
    points: np.ndarray
    directions: np.ndarray
    arclength: np.ndarray
    length: float
    requested: float
    complete: bool

    @property
    def end_point(self) -> np.ndarray:
        """(3,) position of the last point."""
        return self.points[-1]


@dataclass(frozen=True)
class _FanFace:
    face: int
    lv: int  # local index of the centre vertex
    ls: int  # local index of the vertex on the start ray
    le: int  # local index of the vertex on the end ray
    phi: float  # angle of the start ray, measured around the vertex from the walk's face
    theta: float  # corner angle


@dataclass(frozen=True)
class _State:
    face: int
    bary: np.ndarray
    direction: np.ndarray


def _describe(name: str | None) -> str:
    return f"clutch {name!r}" if name else "the path"


def _corner(topo: MeshTopology, face: int, lv: int, ls: int, phi: float) -> _FanFace:
    le = 3 - lv - ls
    P = topo.V[topo.F[face]]
    a, c = P[ls] - P[lv], P[le] - P[lv]
    theta = math.atan2(float(np.linalg.norm(np.cross(a, c))), float(a @ c))
    return _FanFace(face, lv, ls, le, phi, theta)


def _local(topo: MeshTopology, face: int, vertex: int) -> int:
    row = topo.F[face]
    return 0 if row[0] == vertex else 1 if row[1] == vertex else 2 if row[2] == vertex else -1


def _vertex_fan(topo: MeshTopology, face: int, lv: int) -> tuple[list[_FanFace], bool]:
    """Faces around vertex ``F[face, lv]`` in angular order, angles from ``face``'s start ray.

    Returns the fan (sorted by angle) and whether it is closed (interior vertex)."""
    v = int(topo.F[face, lv])
    first = _corner(topo, face, lv, (lv + 1) % 3, 0.0)
    fwd, closed, cur = [first], False, first
    for _ in range(_MAX_FAN):  # forward: across the edge (v, end vertex)
        g = int(topo.neighbor[cur.face, cur.ls])
        if g < 0:
            break
        if g == face:
            closed = True
            break
        glv = _local(topo, g, v)
        gle = int(topo.neighbor_edge[cur.face, cur.ls])
        if glv < 0 or glv == gle:
            break
        cur = _corner(topo, g, glv, 3 - glv - gle, cur.phi + cur.theta)
        fwd.append(cur)
    if closed:
        return fwd, True
    back, cur = [], first
    for _ in range(_MAX_FAN):  # backward: across the edge (v, start vertex)
        h = int(topo.neighbor[cur.face, cur.le])
        if h < 0 or h == face:
            break
        hlv = _local(topo, h, v)
        hls = int(topo.neighbor_edge[cur.face, cur.le])
        if hlv < 0 or hlv == hls:
            break
        c = _corner(topo, h, hlv, hls, 0.0)
        cur = _FanFace(c.face, c.lv, c.ls, c.le, cur.phi - c.theta, c.theta)
        back.append(cur)
    return back[::-1] + fwd, False


def _ray_frame(topo: MeshTopology, ff: _FanFace) -> tuple[np.ndarray, np.ndarray]:
    """Unit start-ray vector and the in-plane unit vector perpendicular to it, towards
    the end ray."""
    P = topo.V[topo.F[ff.face]]
    a = P[ff.ls] - P[ff.lv]
    a = a / np.linalg.norm(a)
    t = P[ff.le] - P[ff.lv]
    t = t - (t @ a) * a
    return a, t / np.linalg.norm(t)


def _leave_vertex(
    topo: MeshTopology, face: int, lv: int, direction: np.ndarray, through: bool
) -> _State | None:
    """Continue a walk at vertex ``F[face, lv]``.

    direction : (3,) unit vector in the plane of ``face``. With ``through`` it is the
    direction the walk arrived with (from inside ``face``); otherwise it is the wanted
    outgoing direction, given by its angle in ``face`` unfolded around the vertex.
    Returns None if the continuation leaves the mesh."""
    fan, closed = _vertex_fan(topo, face, lv)
    ref = next(x for x in fan if x.face == face and x.phi == 0.0)
    a, t = _ray_frame(topo, ref)
    lo, hi = fan[0].phi, fan[-1].phi + fan[-1].theta
    if through:  # angle of the way back, inside ``face``
        phi_in = math.atan2(float(-direction @ t), float(-direction @ a))
        phi_in = min(max(phi_in, 0.0), ref.theta)
        cands = [phi_in + 0.5 * (hi - lo)] if closed else [phi_in + math.pi, phi_in - math.pi]
    else:
        cands = [math.atan2(float(direction @ t), float(direction @ a))]
    if closed:
        phi = lo + (cands[0] - lo) % (hi - lo)
    else:
        tol = 1e-9
        inside = [p for p in cands if lo - tol <= p <= hi + tol]
        if not inside:
            return None
        phi = min(max(inside[0], lo), hi)
    ff = fan[-1]
    for cand in fan:
        if phi <= cand.phi + cand.theta:
            ff = cand
            break
    gamma = min(max(phi - ff.phi, 0.0), ff.theta)
    a, t = _ray_frame(topo, ff)
    d = math.cos(gamma) * a + math.sin(gamma) * t
    b = np.zeros(3)
    b[ff.lv] = 1.0
    return _State(ff.face, b, d / np.linalg.norm(d))


def _clean(b: np.ndarray) -> np.ndarray:
    b = np.maximum(b, 0.0)
    return b / b.sum()


def trace_path(
    V: np.ndarray,
    F: np.ndarray,
    start_face: int,
    start_bary: np.ndarray,
    direction: np.ndarray,
    length: float,
    *,
    topology: MeshTopology | None = None,
    clip: bool = False,
    name: str | None = None,
) -> SurfacePath:
    """Walk straight ahead on the surface for ``length`` metres.

    Parameters
    ----------
    V : (n, 3) float64 vertex positions, metres; F : (m, 3) int64 triangles.
    start_face : int; start_bary : (3,) barycentric coordinates in ``start_face``
        (non-negative, summing to 1; small round-off is cleaned).
    direction : (3,) 3D tangent vector; it is projected onto the plane of ``start_face``
        and normalised (its length does not matter).
    length : float, metres (> 0).
    topology : precomputed :class:`MeshTopology` of (V, F); built here if None (build it
        once and pass it when walking many times on one mesh).
    clip : stop at the mesh boundary instead of raising :class:`ClutchError`.
    name : clutch name used in error messages.
    """
    topo = topology if topology is not None else MeshTopology(V, F)
    who = _describe(name)
    if not topo.matches(np.asarray(V), np.asarray(F)):
        raise ClutchError(f"{who}: the topology was built for another mesh")
    m = topo.n_faces
    if not 0 <= int(start_face) < m:
        raise ClutchError(f"{who}: start face {start_face} is not a face of the mesh (0..{m - 1})")
    if not (math.isfinite(length) and length > 0):
        raise ClutchError(f"{who}: length must be > 0, got {length}")
    f = int(start_face)
    b = np.asarray(start_bary, dtype=np.float64).reshape(3)
    if not np.all(np.isfinite(b)) or b.min() < -1e-6 or abs(b.sum() - 1.0) > 1e-6:
        raise ClutchError(f"{who}: start barycentric coordinates {b.tolist()} are not in the face")
    b = _clean(b)
    d = np.asarray(direction, dtype=np.float64).reshape(3)
    d = d - (d @ topo.normal[f]) * topo.normal[f]
    nd = float(np.linalg.norm(d))
    if not (math.isfinite(nd) and nd > 1e-12 * max(1.0, float(np.abs(direction).max()))):
        raise ClutchError(f"{who}: direction is zero or normal to the surface at the start")
    d = d / nd

    faces, barys, dirs, arcs = [], [], [], []

    def record(f_: int, b_: np.ndarray, d_: np.ndarray, s_: float) -> None:
        if arcs and s_ == arcs[-1]:  # zero-length step: same point, newer face
            faces.pop(), barys.pop(), dirs.pop(), arcs.pop()
        faces.append(f_), barys.append(b_), dirs.append(d_), arcs.append(s_)

    def stop(s_: float) -> SurfacePath:
        B = np.array(barys)
        fa = np.array(faces, dtype=np.int64)
        pts = np.einsum("kj,kjx->kx", B, topo.V[topo.F[fa]])
        return SurfacePath(fa, B, pts, np.array(dirs), np.array(arcs), float(s_),
                           float(length), s_ == length)

    def boundary(s_: float) -> SurfacePath:
        if clip:
            return stop(s_)
        raise ClutchError(
            f"{who} leaves the garment after {100 * s_:.1f} cm of {100 * length:.1f} cm; allowed: a clutch that "
            f"fits on the garment (make it at most {100 * s_:.1f} cm long, or move its start or turn it inwards)"
        )

    s = 0.0
    kv = int(np.argmax(b))
    if b[kv] >= 1.0 - _SNAP:  # start on a vertex: place the direction in the one-ring
        st = _leave_vertex(topo, f, kv, d, through=False)
        if st is None:
            record(f, b, d, s)
            return boundary(s)
        f, b, d = st.face, st.bary, st.direction
    record(f, b, d, s)

    inward, grad, normal = topo.inward, topo.grad, topo.normal
    nbr, nbr_e, Fm = topo.neighbor, topo.neighbor_edge, topo.F
    for _ in range(100 * m + 1000):
        c = inward[f] @ d
        db = grad[f] @ d
        t_exit, i_exit = math.inf, -1
        for i in range(3):
            if c[i] < -_EPS_DIR:
                ti = b[i] / -db[i]
                if ti < t_exit:
                    t_exit, i_exit = ti, i
        remaining = length - s
        if t_exit >= remaining:
            b = _clean(b + remaining * db)
            record(f, b, d, length)
            return stop(length)
        b = b + t_exit * db
        b[i_exit] = 0.0
        b = _clean(b)
        s += t_exit
        u, w = (i_exit + 1) % 3, (i_exit + 2) % 3
        if min(b[u], b[w]) <= _SNAP:  # exit through a vertex
            lv = u if b[u] > b[w] else w
            st = _leave_vertex(topo, f, lv, d, through=True)
            if st is None:
                record(f, b, d, s)
                return boundary(s)
            f, b, d = st.face, st.bary, st.direction
        else:
            g = int(nbr[f, i_exit])
            if g < 0:
                record(f, b, d, s)
                return boundary(s)
            j = int(nbr_e[f, i_exit])
            bg = np.zeros(3)
            if Fm[g, (j + 1) % 3] == Fm[f, u]:
                bg[(j + 1) % 3], bg[(j + 2) % 3] = b[u], b[w]
            else:
                bg[(j + 1) % 3], bg[(j + 2) % 3] = b[w], b[u]
            din = inward[f, i_exit]
            d = d - (d @ din) * (din + inward[g, j])
            d = d - (d @ normal[g]) * normal[g]
            d = d / np.linalg.norm(d)
            f, b = g, bg
        record(f, b, d, s)
    raise ClutchError(f"{who}: the surface walk made no progress (degenerate mesh?)")
