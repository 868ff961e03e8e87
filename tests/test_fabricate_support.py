"""Shared helpers for the fabrication tests: the 563-face right arm sleeve, its elbow clutch,
synthetic designs on it, and a fake run folder as ``kgarment design`` leaves it."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

SLEEVE = """
[garment]
template = "arm_sleeve.right"
subdivision = 0
[motions]
use = ["arm_flexion.right"]
[materials]
preset = "reference"
[design]
target_area = 0.2
"""


def arm_band(body, garment, strip, half_angle: float = 40.0, side: str = "R"):
    """((m,) bool faces within ``half_angle`` degrees of the clutch around the arm's axis,
    (m,) cosine of each face's angle to the clutch's side)."""
    V, F = garment.rest_vertices, garment.faces
    J = body.rest_joints
    pts = [J[body.bone_index(f"{b}.{side}")] for b in ("upperarm02", "lowerarm01", "wrist")]

    def radial(p):
        best = None
        for a, b in itertools.pairwise(pts):
            d = b - a
            t = np.clip(((p - a) @ d) / (d @ d), 0, 1)
            r = p - (a + t[:, None] * d)
            best = r if best is None else np.where(
                (np.linalg.norm(r, axis=1) < np.linalg.norm(best, axis=1))[:, None], r, best)
        return best / np.linalg.norm(best, axis=1, keepdims=True)

    ref = radial(strip.vertices[strip.centerline])
    rc = radial(V[F].mean(axis=1))
    return (rc @ ref.T).max(axis=1) > np.cos(np.radians(half_angle)), rc @ ref.mean(axis=0)


@pytest.fixture(scope="session")
def sleeve(anny_body):
    from kgarment.garment import make_garment

    return make_garment(anny_body, "arm_sleeve.right", 0)


@pytest.fixture(scope="session")
def sleeve_clutches(anny_body, sleeve):
    from kgarment.clutch import build_clutch
    from kgarment.clutch.layouts import default_layout

    specs = default_layout("arm_flexion", anny_body)
    return specs, [build_clutch(s, sleeve.rest_vertices, sleeve.faces) for s in specs]


@pytest.fixture(scope="session")
def band_design(anny_body, sleeve, sleeve_clutches):
    """(design (m,) 1 / 1e-3: a band along the arm under the clutch plus a one-face island
    on the far side, the island's face id)."""
    band, score = arm_band(anny_body, sleeve, sleeve_clutches[1][0])
    far = np.flatnonzero(~sleeve.attached & (score < -0.5))
    island = int(far[0])
    solid = band.copy()
    solid[island] = True
    return np.where(solid, 1.0, 1e-3), island


def write_run(run, sleeve, specs, design, iterations: int = 3):
    """A fake run folder: problem.toml, clutches.toml, designs.npz and final/design.npz."""
    import tomllib

    import tomli_w

    from kgarment.clutch import save_clutches
    from kgarment.problem import parse_problem, problem_to_dict

    run.mkdir(parents=True)
    p = parse_problem(tomllib.loads(SLEEVE))
    save_clutches(run / "clutches.toml", specs, sleeve.rest_vertices, sleeve.faces)
    (run / "problem.toml").write_text(tomli_w.dumps(problem_to_dict(p, run / "clutches.toml")))
    solid = design > 0.5
    hist = [np.ones_like(solid)] * (iterations - 1) + [solid]
    np.savez(run / "designs.npz", designs=np.array([np.packbits(h) for h in hist]), n_faces=np.array(len(solid)))
    (run / "final").mkdir()
    np.savez(run / "final" / "design.npz", design=design, faces=sleeve.faces, rest_vertices=sleeve.rest_vertices)
    return run
