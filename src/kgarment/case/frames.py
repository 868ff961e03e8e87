"""A motion's frames from rest to its target pose, for the force over the motion
(:mod:`kgarment.evaluate.path`) and the design loop's motion start (``[solver] path_start``)."""

from __future__ import annotations

import dataclasses

import numpy as np

from kgarment.body.motions import Motion as BodyMotion
from kgarment.case.keys import early_motion, frame_motion
from kgarment.errors import KgarmentError
from kgarment.sim import garment_motions

REST = "rest"  # the frame name of the rest pose (t = 0 of every motion)


def frame_motions(problem, motions, frames: int, rest: bool = False,
                  attached=None) -> tuple[dict, list[tuple[str, str, float]]]:
    """({frame name: kgarment.sim.Motion}, [(frame name, motion, t)]): ``problem``'s garment
    on its body posed at ``t = i / frames`` of each motion of ``motions`` (i = 1..frames);
    with ``rest`` also the rest pose, shared by every motion, as frame :data:`REST` (not in
    the list).  ``attached`` : (m,) bool, the garment's attached faces where they are not
    the problem's (the studio's painted attachments)."""
    if problem.body.model != "anny":
        raise KgarmentError("the motion from rest (--path, [solver] path_start) needs a posable body (body "
                            "model 'anny'): a mesh sequence has only the target poses")
    if frames < 1:
        raise KgarmentError(f"--path {frames}: the number of frames must be at least 1")
    lib = {m.name: m for m in problem.motion_list()}
    index, poses = [], []
    for name in motions:
        for i in range(1, frames + 1):
            t = i / frames
            label = frame_motion(name, t)
            poses.append(BodyMotion(label, (lib[name].at(t),)))
            index.append((label, name, t))
    if rest and motions:
        poses.append(BodyMotion(REST, (lib[motions[0]].at(0.0),)))
    return _posed(problem, poses, attached), index


def early_motions(problem) -> dict:
    """{``MOTION@t``: kgarment.sim.Motion}: the garment on the body posed at the share t of
    each motion of ``problem``'s ``[design] early`` (empty without it)."""
    if not problem.design.early:
        return {}
    lib = {m.name: m for m in problem.motion_list()}
    poses = [BodyMotion(early_name(m, t), (lib[m].at(t),)) for m, t in problem.design.early]
    return _posed(problem, poses)


def early_shares(early) -> dict[str, float]:
    """{design state name: its share of the objective} of ``[design] early`` ((motion, t),
    ...): a motion and its k early poses 1 / (1 + k) each, so that together they count as
    one motion (:mod:`kgarment.optimize.objective`)."""
    k = {}
    for m, _ in early:
        k[m] = k.get(m, 0) + 1
    out = {m: 1.0 / (1 + n) for m, n in k.items()}
    out.update({early_name(m, t): out[m] for m, t in early})
    return out


def objective_shares(early, weights) -> dict[str, float]:
    """{design state name: its share of the objective}: :func:`early_shares` of ``[design]
    early`` times each motion's ``[design] weights`` ((motion, w), ...; a motion not named:
    1), a motion's early poses taking its weight."""
    out = early_shares(early)
    for m, w in weights:
        out[m] = out.get(m, 1.0) * w
    out.update({early_name(m, t): out[m] for m, t in early})  # an early pose shares its motion's
    return out


def early_name(motion: str, t: float) -> str:
    """The design state name of ``motion`` at the share ``t`` of its movement."""
    return early_motion(motion, t)


def _posed(problem, poses, attached=None) -> dict:
    """{pose name: kgarment.sim.Motion}: ``problem``'s garment on its Anny body posed as
    ``poses`` (body motions); ``attached`` as in :func:`frame_motions`."""
    from kgarment.body.anny_backend import load_anny_body
    from kgarment.problem import build_garment

    body = load_anny_body(poses, problem.body.phenotype)
    garment = build_garment(problem, body)
    if attached is not None:
        mask = np.asarray(attached, dtype=bool)
        if mask.shape != garment.attached.shape:
            raise KgarmentError(f"{mask.size} attachment flags for a garment of {garment.attached.size} faces")
        garment = dataclasses.replace(garment, attached=mask)
    return garment_motions(body, garment)
