"""The connected BESO update on flat strips: a cut series link restored, islands dropped,
a band around the body recognised as held, proposals already in one piece left alone."""

from __future__ import annotations

import numpy as np

from kgarment.evaluate.metrics import clutch_end_support, islands
from kgarment.garment.topology import face_adjacency, triangle_areas
from kgarment.optimize.connect import anchored, connect_design


def strip(nx: int = 61, ny: int = 21, length: float = 0.3, width: float = 0.1):
    """A flat length x width strip: vertices (n, 3), faces (m, 3), centroids (m, 3), areas
    (m,) and the faces of its left and right short edges (held, like attachment rings)."""
    xs, ys = np.linspace(-length / 2, length / 2, nx), np.linspace(-width / 2, width / 2, ny)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    v = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], 1)
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="ij")
    a = (i * ny + j).ravel()
    f = np.concatenate([np.stack([a, a + ny, a + ny + 1], 1), np.stack([a, a + ny + 1, a + 1], 1)])
    c = v[f].mean(axis=1)
    edge = length / 2 - 0.006
    return v, f, c, triangle_areas(v, f), np.flatnonzero(np.abs(c[:, 0]) > edge)


def ends_at(c, x0, x1, y=0.0):
    """The 3 faces nearest to (x0, y) and to (x1, y): a clutch from x0 to x1."""
    near = lambda x: np.argsort(np.hypot(c[:, 0] - x, c[:, 1] - y))[:3]  # noqa: E731
    return near(x0), near(x1)


def cut_link(c):
    """A clutch in the middle of the strip and a proposal around it: the band left of the
    clutch, the band right of it stopping 2 cm short of the right edge, and a loose patch
    beside the clutch -> (ends, left, right, loose), each (m,) bool but ends."""
    band = np.abs(c[:, 1]) < 0.02
    left = band & (c[:, 0] < -0.03)
    right = band & (c[:, 0] > 0.03) & (c[:, 0] < 0.125)
    loose = (np.abs(c[:, 0]) < 0.02) & (c[:, 1] > 0.035)
    return [ends_at(c, -0.04, 0.04)], left, right, loose


def test_a_proposal_that_holds_every_clutch_is_left_alone():
    v, f, c, areas, held = strip()
    ends = [ends_at(c, -0.04, 0.04)]
    band = np.abs(c[:, 1]) < 0.02  # a band from the left edge to the right edge along the clutch
    alpha = np.where(band, 1.0, 0.0) + 1e-3 * c[:, 0]
    target = areas[band].sum() / areas.sum()
    out = connect_design(band, alpha, areas, target, face_adjacency(f), ends, held)
    np.testing.assert_array_equal(out, band)


def test_a_cut_series_link_is_restored_and_islands_dropped():
    """A clutch in the middle of a strip held at both short edges.  BESO proposes the left
    half up to the clutch's start, a patch around its end that stops 2 cm short of the right
    edge (the link ranks low), and a loose patch: the repair joins the clutch's end to the
    right edge (so the clutch is in series between the held edges), drops the loose patch
    and keeps the area."""
    v, f, c, areas, held = strip()
    ends, left, right, loose = cut_link(c)
    proposal = left | right | loose
    alpha = np.where(left | right, 1.0, 0.05) + np.where(loose, 0.5, 0.0) - 0.01 * np.abs(c[:, 1])
    target = areas[left | right | loose].sum() / areas.sum()
    adj = face_adjacency(f)
    out = connect_design(proposal, alpha, areas, target, adj, ends, held)
    assert not (out & loose).any()
    assert all(a and b for a, b in clutch_end_support(out, ends))
    assert islands(f, out, links=ends) == 1
    assert islands(f, out) == 2  # in two parts without the clutch: the clutch is their only link
    assert (out & (c[:, 0] > 0.14)).any()  # the right part reaches the held edge
    assert abs(areas[out].sum() / areas.sum() - target) < 3 * areas.max() / areas.sum()


def test_two_clutches_in_a_v_are_joined_at_their_meeting_ends():
    """Two clutches from the held edges' parts towards the middle; BESO drops the pad
    joining their inner ends: the repair puts it back, so the chain left part - clutch -
    pad - clutch - right part holds (and no reinforced path bypasses the clutches)."""
    v, f, c, areas, held = strip()
    ends = [ends_at(c, -0.10, -0.015), ends_at(c, 0.10, 0.015)]
    band = np.abs(c[:, 1]) < 0.015
    outer = band & (np.abs(c[:, 0]) > 0.09)
    pad = band & (np.abs(c[:, 0]) < 0.03)
    alpha = np.where(outer, 1.0, 0.02) - 0.01 * np.abs(c[:, 1])
    target = areas[outer | pad].sum() / areas.sum()
    adj = face_adjacency(f)
    out = connect_design(outer, alpha, areas, target, adj, ends, held)
    assert all(a and b for a, b in clutch_end_support(out, ends))
    assert islands(f, out, links=ends) == 1 and islands(f, out) == 3
    assert not (out & (np.abs(c[:, 0]) > 0.04) & (np.abs(c[:, 0]) < 0.08)).any()  # no bypass


def test_clutches_never_on_together_are_each_held_without_the_other():
    """The V of the test above, but the two clutches are never switched on together
    (selective activation): the pad joining their inner ends is held only through the other
    clutch, which is OFF whenever this one is ON, so each inner end gets its own reinforced
    path to a held edge that does not pass the other clutch."""
    v, f, c, areas, held = strip()
    ends = [ends_at(c, -0.10, -0.015), ends_at(c, 0.10, 0.015)]
    band = np.abs(c[:, 1]) < 0.015
    outer = band & (np.abs(c[:, 0]) > 0.09)
    pad = band & (np.abs(c[:, 0]) < 0.03)
    alpha = np.where(outer | pad, 1.0, 0.02) - 0.01 * np.abs(c[:, 1])
    target = 1.5 * areas[outer | pad].sum() / areas.sum()
    adj = face_adjacency(f)
    together = connect_design(outer | pad, alpha, areas, target, adj, ends, held)
    apart = connect_design(outer | pad, alpha, areas, target, adj, ends, held, partners=[[], []])
    for out in (together, apart):
        assert all(a and b for a, b in clutch_end_support(out, ends))
    # all ON together: the chain through both clutches holds, nothing else is needed
    assert islands(f, together) == 3 and islands(f, together, links=ends) == 1
    # never together: each clutch's inner end reaches a held edge over reinforcement
    # without the other clutch, i.e. the pad is joined to an outer part
    assert islands(f, apart) < 3
    for a, b in ends:
        for end in (a, b):
            assert reached(f, apart, end, [])[held].any()
    assert not all(reached(f, together, b, [])[held].any() for _, b in ends)  # the pad alone is not held


def reached(f, solid, start, links):
    """(m,) bool faces of ``solid`` joined to ``start`` through solid faces and ``links``."""
    from kgarment.optimize.connect import _reachable, link_graph

    return _reachable(link_graph(face_adjacency(f), links), solid, int(start[0]))


def test_a_band_around_a_tube_is_held_an_open_patch_is_not():
    """On a tube (two boundary rings, nothing attached) a band around it separates the two
    openings (the body cannot slip out of it); a patch on one side does not."""
    from kgarment.garment.topology import boundary_loops
    from kgarment.sim.synthetic import Tube

    tube = Tube(0.05, 0.0, 0.3, 24, 16)
    f = tube.faces
    c = tube.vertices[f].mean(axis=1)
    n = len(tube.vertices)
    loops = [np.flatnonzero(np.isin(f, loop).any(axis=1)) for loop in boundary_loops(f)]
    assert len(loops) == 2 and n > 0
    adj = face_adjacency(f)
    band = np.abs(c[:, 2] - 0.15) < 0.03
    patch = band & (c[:, 0] > 0.02)
    assert anchored(band, adj, np.zeros(0, int), loops)[band].all()
    assert not anchored(patch, adj, np.zeros(0, int), loops).any()
    ring = np.flatnonzero(c[:, 2] < 0.02)
    assert anchored(patch | np.isin(np.arange(len(f)), ring), adj, ring, loops)[ring].all()


def test_the_trim_keeps_the_band_a_clutch_end_is_held_by():
    """On a tube (nothing attached) a clutch along it with each end on a band around it;
    the band of end A ranks lowest and the area must shrink.  The trim removes the ranked
    tail beyond the upper band and leaves the lower band closed: opening it would leave end A
    joined to the rest only through its own clutch, holding nothing (the trim that checked
    only the root's part kept 4 of the band's 48 faces and end A was held by nothing)."""
    from kgarment.garment.topology import boundary_loops
    from kgarment.sim.synthetic import Tube

    tube = Tube(0.05, 0.0, 0.3, 24, 31)
    f = tube.faces
    c = tube.vertices[f].mean(axis=1)
    areas = triangle_areas(tube.vertices, f)
    loops = [np.flatnonzero(np.isin(f, loop).any(axis=1)) for loop in boundary_loops(f)]
    theta = np.arctan2(c[:, 1], c[:, 0])
    near = lambda z: np.argsort(np.hypot(c[:, 2] - z, 0.05 * np.abs(theta)))[:3]
    ends = [(near(0.105), near(0.2))]
    band_a = np.abs(c[:, 2] - 0.105) < 0.004  # one row of triangles: removing a few opens it
    band_b = np.abs(c[:, 2] - 0.2) < 0.012
    tail = (c[:, 2] > 0.2) & (c[:, 2] < 0.27) & (np.abs(theta) < 0.6)
    proposal = band_a | band_b | tail
    alpha = np.where(band_b, 1.0, np.where(tail, 0.5, 0.1)) + 1e-3 * c[:, 2]
    adj = face_adjacency(f)
    assert anchored(proposal, adj, np.zeros(0, int), loops)[band_a].all()
    target = 0.8 * areas[proposal].sum() / areas.sum()
    out = connect_design(proposal, alpha, areas, target, adj, ends, np.zeros(0, int), loops)
    held = anchored(out, adj, np.zeros(0, int), loops)
    assert held[ends[0][0][out[ends[0][0]]]].any() and held[ends[0][1][out[ends[0][1]]]].any()
    assert (out & band_a).sum() >= band_a.sum() - 2 and held[band_a & out].all()  # still around the tube
    assert (tail & ~out).sum() > tail.sum() / 2  # the area came from the tail
    assert abs(areas[out].sum() / areas.sum() - target) < 3 * areas.max() / areas.sum()


def test_no_clutches_no_change():
    v, f, c, areas, held = strip(21, 11)
    solid = c[:, 0] > 0.05
    out = connect_design(solid, c[:, 0], areas, 0.2, face_adjacency(f), [], held)
    np.testing.assert_array_equal(out, solid)


def test_a_clutch_held_only_by_an_edge_the_proposal_misses_is_joined_in():
    """A clutch near the right held edge while BESO proposes only the left half: the path
    from each of its ends to the edge is joined to the rest, not dropped as an island."""
    v, f, c, areas, held = strip()
    ends = [ends_at(c, 0.08, 0.12)]
    left = (c[:, 0] < -0.05) & (np.abs(c[:, 1]) < 0.02)
    alpha = np.where(left, 1.0, 0.1) - 0.01 * np.abs(c[:, 1])
    target = areas[left].sum() / areas.sum()
    out = connect_design(left, alpha, areas, target, face_adjacency(f), ends, held)
    assert all(a and b for a, b in clutch_end_support(out, ends))
    assert islands(f, out, links=ends) == 1


def test_any_proposal_comes_out_in_one_part_holding_every_clutch_at_the_target_area():
    """Invariant over random proposals and rankings: one part counting clutches as links,
    every clutch end on reinforcement, the target area met to within a few faces."""
    v, f, c, areas, held = strip(41, 15)
    adj = face_adjacency(f)
    ends = [ends_at(c, -0.10, -0.03, 0.02), ends_at(c, 0.02, 0.11, -0.02), ends_at(c, -0.02, 0.05, 0.03)]
    rng = np.random.default_rng(7)
    for _ in range(12):
        smooth = np.sin(rng.uniform(5, 40) * c[:, 0] + rng.uniform(0, 6)) * np.cos(rng.uniform(5, 60) * c[:, 1])
        alpha = smooth + 0.05 * rng.random(len(f))
        target = rng.uniform(0.15, 0.35)
        proposal = alpha >= np.quantile(alpha, 1.0 - target)
        out = connect_design(proposal, alpha, areas, target, adj, ends, held)
        assert all(a and b for a, b in clutch_end_support(out, ends))
        assert islands(f, out, links=ends, adjacency=adj) == 1
        assert abs(areas[out].sum() / areas.sum() - target) < 4 * areas.max() / areas.sum()


def test_kept_faces_stay_joined_to_the_structure():
    """Faces the step guard keeps are neither dropped as islands nor trimmed, though they
    rank low: the loose patch of the cut-link proposal, kept, is joined to the rest."""
    v, f, c, areas, held = strip()
    ends, left, right, loose = cut_link(c)
    proposal = left | right | loose
    alpha = np.where(left | right, 1.0, 0.05) - 0.01 * np.abs(c[:, 1])
    target = areas[proposal].sum() / areas.sum()
    adj = face_adjacency(f)
    out = connect_design(proposal, alpha, areas, target, adj, ends, held, keep=loose)
    assert out[loose].all()
    assert islands(f, out, links=ends, adjacency=adj) == 1
    assert abs(areas[out].sum() / areas.sum() - target) < 0.01


def test_clutch_ends_are_joined_to_what_the_body_holds_not_to_a_floating_part():
    """A proposal around the clutch that reaches neither held edge (all of it floats on the
    body, however sensitive): the repair joins the clutch's ends to a held edge."""
    v, f, c, areas, held = strip()
    ends = [ends_at(c, -0.04, 0.04)]
    patch = (np.abs(c[:, 0]) < 0.07) & (np.abs(c[:, 1]) < 0.02)
    alpha = np.where(patch, 1.0, 0.0) - 0.01 * np.abs(c[:, 0])
    target = 1.5 * areas[patch].sum() / areas.sum()
    adj = face_adjacency(f)
    out = connect_design(patch, alpha, areas, target, adj, ends, held)
    holding = anchored(out, adj, held, ())
    assert all(holding[a].all() and holding[b].all() for a, b in ends)
