"""Straight-ahead surface walk (kgarment.clutch.walk) on analytic meshes."""

from __future__ import annotations

import time

import numpy as np
import pytest
import trimesh

from kgarment.clutch import ClutchError, MeshTopology, SurfacePath, trace_path
from kgarment.clutch.samples import flat_sheet, open_prism, prism_point

R, SIDES = 0.05, 24


@pytest.fixture(scope="module")
def sheet():
    V, F = flat_sheet(0.3, 40, jitter=0.3, thin=True, seed=1)
    return V, F, MeshTopology(V, F)


@pytest.fixture(scope="module")
def grid():
    V, F = flat_sheet(0.3, 30)  # regular: 1 cm squares, all diagonals the same way
    return V, F, MeshTopology(V, F)


@pytest.fixture(scope="module")
def prism():
    V, F = open_prism(R, 0.3, SIDES, 60)
    return V, F, MeshTopology(V, F)


@pytest.fixture(scope="module")
def sphere():
    m = trimesh.creation.icosphere(subdivisions=4, radius=0.1)
    V, F = np.asarray(m.vertices, float), np.asarray(m.faces, np.int64)
    return V, F, MeshTopology(V, F)


def tangent(topo, face, v):
    n = topo.normal[face]
    v = np.asarray(v, float)
    v = v - (v @ n) * n
    return v / np.linalg.norm(v)


def random_walks(V, F, topo, k, length, seed, region=None):
    """k random (face, bary, direction) starts; ``region`` filters face centroids."""
    rng = np.random.default_rng(seed)
    ok = np.arange(len(F)) if region is None else np.flatnonzero(region(V[F].mean(axis=1)))
    for _ in range(k):
        f = int(rng.choice(ok))
        yield f, rng.dirichlet([2, 2, 2]), tangent(topo, f, rng.normal(size=3))


def polyline_length(p: SurfacePath) -> float:
    return float(np.linalg.norm(np.diff(p.points, axis=0), axis=1).sum())


def assert_on_surface(p: SurfacePath, topo: MeshTopology):
    """Every point is on the mesh, and each segment lies in one face (point k+1 is in
    face k): the path really is the polyline through the faces."""
    for q in p.points[:: max(1, len(p.points) // 15)]:
        assert topo.closest_point(q).distance < 1e-12
    for k in range(len(p.points) - 1):
        f = p.faces[k]
        P = topo.V[topo.F[f]]
        assert abs((p.points[k + 1] - P[0]) @ topo.normal[f]) < 1e-12
        b = topo.grad[f] @ (p.points[k + 1] - P[0])
        b[0] = 1 - b[1] - b[2]
        assert b.min() > -1e-9
    assert np.allclose(p.bary.sum(axis=1), 1.0) and p.bary.min() >= 0.0
    assert np.allclose(np.linalg.norm(p.directions, axis=1), 1.0)
    assert np.allclose(np.einsum("kj,kj->k", p.directions, topo.normal[p.faces]), 0.0, atol=1e-12)


def inside_sheet(c):
    return (np.abs(c[:, 0] - 0.15) < 0.05) & (np.abs(c[:, 1] - 0.15) < 0.05)


@pytest.mark.parametrize("mesh", ["sheet", "prism", "sphere"])
def test_length_is_exact_and_path_on_surface(mesh, request):
    V, F, topo = request.getfixturevalue(mesh)
    region = {"sheet": inside_sheet, "prism": lambda c: np.abs(c[:, 2] - 0.15) < 0.02}.get(mesh)
    length = 0.09 if mesh == "sheet" else 0.12
    for f, b, d in random_walks(V, F, topo, 6, length, seed=3, region=region):
        p = trace_path(V, F, f, b, d, length, topology=topo)
        assert p.complete and p.length == length and p.arclength[-1] == length
        assert abs(polyline_length(p) - length) < 1e-9 * length
        assert np.allclose(np.diff(p.arclength), np.linalg.norm(np.diff(p.points, axis=0), axis=1))
        assert_on_surface(p, topo)


def test_flat_sheet_path_is_the_straight_line(sheet):
    V, F, topo = sheet
    for f, b, d in random_walks(V, F, topo, 8, 0.09, seed=5, region=inside_sheet):
        p = trace_path(V, F, f, b, d, 0.09, topology=topo)
        x0 = p.points[0]
        off = (p.points - x0) - np.outer((p.points - x0) @ d, d)
        assert np.abs(off).max() < 1e-12
        assert np.allclose(p.end_point, x0 + 0.09 * d, atol=1e-12, rtol=0)
        assert len(p.points) > 10  # crossed many (thin) triangles


def test_prism_path_is_the_unrolled_straight_line(prism):
    """A geodesic on a prism is a straight line of the unrolled facets: a helix."""
    V, F, topo = prism
    chord = 2 * R * np.sin(np.pi / SIDES)
    for u0, z0, alpha, length in [(0.013, 0.05, 0.4, 0.2), (0.2, 0.1, -2.9, 0.25),
                                   (0.05, 0.15, 1.2, 0.12), (0.31, 0.2, -0.05, 0.3)]:
        x0 = prism_point(u0, z0, R, SIDES)
        hit = topo.closest_point(x0)
        assert hit.distance < 1e-12
        k = int(u0 // chord)
        along = prism_point((k + 1) * chord, 0, R, SIDES) - prism_point(k * chord, 0, R, SIDES)
        d = np.cos(alpha) * along / chord + np.sin(alpha) * np.array([0, 0, 1.0])
        p = trace_path(V, F, hit.face, hit.bary, d, length, topology=topo)
        u1 = u0 + length * np.cos(alpha)
        expect = prism_point(u1 % (SIDES * chord), z0 + length * np.sin(alpha), R, SIDES)
        assert np.linalg.norm(p.end_point - expect) < 1e-12
        assert abs(polyline_length(p) - length) < 1e-9 * length
        assert_on_surface(p, topo)


@pytest.mark.parametrize("mesh", ["sheet", "sphere", "prism"])
def test_end_point_agrees_with_potpourri3d(mesh, request):
    pp3d = pytest.importorskip("potpourri3d")
    V, F, topo = request.getfixturevalue(mesh)
    tracer = pp3d.GeodesicTracer(V, F)
    region = {"sheet": inside_sheet, "prism": lambda c: np.abs(c[:, 2] - 0.15) < 0.02}.get(mesh)
    for f, b, d in random_walks(V, F, topo, 5, 0.08, seed=11, region=region):
        p = trace_path(V, F, f, b, d, 0.08, topology=topo)
        ref = tracer.trace_geodesic_from_face(f, b, 0.08 * d)
        # (potpourri3d itself is off by ~1e-9 m after the sheet's sliver triangles, where our
        # end point matches the analytic straight line to 1e-12: see the test above)
        assert np.linalg.norm(p.end_point - ref[-1]) < 1e-8


def test_walk_through_vertices_on_a_regular_grid(grid):
    """Diagonal (through vertices, not along edges) and along the grid diagonals (edges)."""
    V, F, topo = grid
    for start, d in [((0.055, 0.145), (1, 1)), ((0.055, 0.145), (1, -1)),  # through vertices
                     ((0.055, 0.055), (1, 1)),  # starts mid-edge, along the diagonal edges
                     ((0.05, 0.1), (2, 1)), ((0.05, 0.2), (1, -2))]:  # vertex to vertex
        hit = topo.closest_point([*start, 0])
        d = np.array([*d, 0.0]) / np.linalg.norm(d)
        p = trace_path(V, F, hit.face, hit.bary, d, 0.12, topology=topo)
        assert np.allclose(p.end_point, hit.point + 0.12 * d, atol=1e-12, rtol=0)
        assert abs(polyline_length(p) - 0.12) < 1e-9 * 0.12
        assert_on_surface(p, topo)


def test_walk_along_edges(grid, prism):
    V, F, topo = grid
    for start, d in [((0.1, 0.105), (1, 0)), ((0.1, 0.105), (-1, 0)), ((0.105, 0.1), (0, 1)),
                     ((0.1, 0.1), (0, -1)), ((0.1, 0.1), (1, 1))]:  # last two: from a vertex
        hit = topo.closest_point([*start, 0])
        d = np.array([*d, 0.0]) / np.linalg.norm(d)
        p = trace_path(V, F, hit.face, hit.bary, d, 0.07, topology=topo)
        assert np.allclose(p.end_point, hit.point + 0.07 * d, atol=1e-12, rtol=0)
        assert abs(polyline_length(p) - 0.07) < 1e-9 * 0.07
    # along a vertical seam (edge) of the prism, and around a ring of edges (a polygon)
    V, F, topo = prism
    v = 5 * 61 + 10  # corner 5, ring 10
    f = int(np.flatnonzero((F == v).any(axis=1))[0])
    b = (F[f] == v).astype(float)
    p = trace_path(V, F, f, b, [0, 0, 1.0], 0.13, topology=topo)
    assert np.allclose(p.end_point, V[v] + [0, 0, 0.13], atol=1e-12, rtol=0)
    along = V[6 * 61 + 10] - V[v]
    p = trace_path(V, F, f, b, along, 0.21, topology=topo)
    chord = 2 * R * np.sin(np.pi / SIDES)
    assert np.linalg.norm(p.end_point - prism_point(5 * chord + 0.21, V[v, 2], R, SIDES)) < 1e-12


def walk_back(p: SurfacePath, topo: MeshTopology) -> SurfacePath:
    return trace_path(topo.V, topo.F, int(p.faces[-1]), p.bary[-1], -p.directions[-1], p.length,
                      topology=topo)


def test_walk_through_a_curved_vertex(sphere):
    """Aim exactly at vertices with an angle defect, and start on them in all directions
    (also outside the start face's corner): the length stays exact, the walk is on the
    surface, and walking back from the end returns to the start (the vertex rule, equal
    angles on both sides, is symmetric)."""
    V, F, topo = sphere
    for v in (0, 17, 400):
        f = int(np.flatnonzero((F == v).any(axis=1))[0])
        b = np.where(F[f] == v, 0.2, 0.4)
        x0 = b @ V[F[f]]
        p = trace_path(V, F, f, b, V[v] - x0, 0.1, topology=topo)
        assert abs(polyline_length(p) - 0.1) < 1e-9 * 0.1
        assert_on_surface(p, topo)
        hits = np.flatnonzero(np.linalg.norm(p.points - V[v], axis=1) < 1e-15)
        assert len(hits) == 1 and 0 < hits[0] < len(p.points) - 1  # went through v
        assert np.linalg.norm(walk_back(p, topo).end_point - x0) < 1e-9
        onehot = (F[f] == v).astype(float)
        n, e = topo.normal[f], V[F[f][F[f] != v][0]] - V[v]
        e /= np.linalg.norm(e)
        for ang in np.linspace(-np.pi, np.pi, 7)[:-1] + 0.1:
            d = np.cos(ang) * e + np.sin(ang) * np.cross(n, e)
            q = trace_path(V, F, f, onehot, d, 0.1, topology=topo)
            assert abs(polyline_length(q) - 0.1) < 1e-9 * 0.1
            assert_on_surface(q, topo)
            assert np.linalg.norm(walk_back(q, topo).end_point - V[v]) < 1e-9


@pytest.mark.parametrize("mesh", ["sheet", "prism", "sphere"])
def test_walking_back_returns_to_the_start(mesh, request):
    V, F, topo = request.getfixturevalue(mesh)
    region = {"sheet": inside_sheet, "prism": lambda c: np.abs(c[:, 2] - 0.15) < 0.02}.get(mesh)
    for f, b, d in random_walks(V, F, topo, 4, 0.08, seed=7, region=region):
        p = trace_path(V, F, f, b, d, 0.08, topology=topo)
        assert np.linalg.norm(walk_back(p, topo).end_point - p.points[0]) < 1e-10


def test_boundary_raises_or_clips(grid, prism):
    V, F, topo = grid
    hit = topo.closest_point([0.05, 0.0731, 0])
    with pytest.raises(ClutchError, match=r"clutch 'upper_back' leaves the garment after 5.0 cm "
                                          r"of 13.5 cm"):
        trace_path(V, F, hit.face, hit.bary, [-1, 0, 0], 0.135, topology=topo, name="upper_back")
    p = trace_path(V, F, hit.face, hit.bary, [-1, 0, 0], 0.135, topology=topo, clip=True)
    assert not p.complete and abs(p.length - 0.05) < 1e-12 and abs(p.end_point[0]) < 1e-12
    # into a corner vertex exactly, and along the boundary edge past boundary vertices
    hit = topo.closest_point([0.03, 0.03, 0])
    p = trace_path(V, F, hit.face, hit.bary, [-1, -1, 0], 0.1, topology=topo, clip=True)
    assert not p.complete and np.allclose(p.end_point, 0, atol=1e-12)
    hit = topo.closest_point([0.1, 0.0, 0])
    p = trace_path(V, F, hit.face, hit.bary, [1, 0, 0], 0.15, topology=topo)
    assert np.allclose(p.end_point, [0.25, 0, 0], atol=1e-12)
    V, F, topo = prism
    hit = topo.closest_point(prism_point(0.02, 0.28, R, SIDES))
    with pytest.raises(ClutchError, match="leaves the garment after 2.0 cm of 10.0 cm"):
        trace_path(V, F, hit.face, hit.bary, [0, 0, 1.0], 0.1, topology=topo, name="x")


def test_bad_arguments(grid):
    V, F, topo = grid
    with pytest.raises(ClutchError, match="length"):
        trace_path(V, F, 0, [1 / 3] * 3, [1, 0, 0], 0.0, topology=topo, name="c")
    with pytest.raises(ClutchError, match="normal to the surface"):
        trace_path(V, F, 0, [1 / 3] * 3, [0, 0, 1], 0.1, topology=topo, name="c")
    with pytest.raises(ClutchError, match="not a face"):
        trace_path(V, F, len(F), [1 / 3] * 3, [1, 0, 0], 0.1, topology=topo, name="c")
    with pytest.raises(ClutchError, match="barycentric"):
        trace_path(V, F, 0, [0.5, 0.7, -0.2], [1, 0, 0], 0.1, topology=topo, name="c")


def test_topology_adjacency_matches_trimesh(sphere, sheet):
    for V, F, topo in (sphere, sheet):
        m = trimesh.Trimesh(V, F, process=False)
        pairs = {tuple(sorted(p)) for p in m.face_adjacency.tolist()}
        ours = {tuple(sorted((f, int(g)))) for f, row in enumerate(topo.neighbor) for g in row
                if g >= 0}
        assert ours == pairs
        f = np.repeat(np.arange(len(F)), 3)[topo.neighbor.ravel() >= 0]
        i = np.tile(np.arange(3), len(F))[topo.neighbor.ravel() >= 0]
        g, j = topo.neighbor[f, i], topo.neighbor_edge[f, i]
        assert np.all(topo.neighbor[g, j] == f)  # symmetric, and the edge indices agree
        shared = np.sort(np.stack([F[f, (i + 1) % 3], F[f, (i + 2) % 3]], 1), axis=1)
        assert np.all(shared == np.sort(np.stack([F[g, (j + 1) % 3], F[g, (j + 2) % 3]], 1), 1))


def test_performance():
    m = trimesh.creation.icosphere(subdivisions=6, radius=0.3)  # 82k faces
    V, F = np.asarray(m.vertices, float), np.asarray(m.faces, np.int64)
    t0 = time.perf_counter()
    MeshTopology(V, F)
    t_topo = time.perf_counter() - t0
    assert t_topo < 1.0, f"topology of {len(F)} faces took {t_topo:.2f} s"
    Vs, Fs = flat_sheet(0.3, 60)  # 5 mm edges
    ts = MeshTopology(Vs, Fs)
    hit = ts.closest_point([0.07, 0.08, 0])
    t0 = time.perf_counter()
    for _ in range(20):
        p = trace_path(Vs, Fs, hit.face, hit.bary, [1, 0.37, 0], 0.15, topology=ts)
    t_walk = (time.perf_counter() - t0) / 20
    assert len(p.points) > 40 and t_walk < 0.02, f"15 cm walk took {1e3 * t_walk:.1f} ms"


def test_winding_does_not_matter(sphere):
    """Faces wound either way: the same walk and the same strip (sides kept consistent)."""
    from kgarment.clutch import ClutchSpec, build_clutch

    V, F, topo = sphere
    rng = np.random.default_rng(0)
    Fx = F.copy()
    flip = rng.random(len(F)) < 0.4
    Fx[flip] = Fx[flip][:, ::-1]
    tx = MeshTopology(V, Fx)
    for f, b, d in random_walks(V, F, topo, 4, 0.1, seed=2):
        p = trace_path(V, F, f, b, d, 0.1, topology=topo)
        bx = b[::-1] if flip[f] else b
        q = trace_path(V, Fx, f, bx, d, 0.1, topology=tx)
        assert np.linalg.norm(p.end_point - q.end_point) < 1e-12
        spec = ClutchSpec("c", (f, bx), d, 0.1)
        s = build_clutch(ClutchSpec("c", (f, b), d, 0.1), V, F, topo)
        sx = build_clutch(spec, V, Fx, tx)
        r = len(s.centerline)
        swap = np.r_[0:r, 2 * r:3 * r, r:2 * r]  # left and right rows exchanged
        expect = s.vertices[swap] if flip[f] else s.vertices  # left = start normal x d
        assert np.abs(sx.vertices - expect).max() < 1e-12


def test_stress_aimed_at_vertices(sheet, sphere):
    """Many walks aimed exactly at vertices (and starting on them) on irregular meshes."""
    for V, F, topo in (sheet, sphere):
        rng = np.random.default_rng(9)
        region = inside_sheet if V[:, 2].max() == 0 else None
        for f, b, _ in random_walks(V, F, topo, 40, 0.05, seed=13, region=region):
            x0 = b @ V[F[f]]
            target = V[F[f, rng.integers(3)]]
            for start_b in (b, np.eye(3)[rng.integers(3)]):
                p = trace_path(V, F, f, start_b, target - x0 + 1e-3 * rng.normal(size=3) * (
                    start_b is not b), 0.05, topology=topo)
                assert abs(polyline_length(p) - 0.05) < 1e-9 * 0.05
                assert np.linalg.norm(walk_back(p, topo).end_point - p.points[0]) < 1e-9
