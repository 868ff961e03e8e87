"""A resolved :class:`~kgarment.problem.spec.Problem` written back as TOML-ready data (a run
folder's ``problem.toml``), which :func:`kgarment.problem.parse.parse_problem` reads back to an
equal problem."""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

from kgarment.problem.spec import MaterialSpec, Problem


def problem_to_dict(problem: Problem, clutch_file: Path | None = None) -> dict:
    """The resolved problem as a TOML-ready dict (paths absolute) that ``parse_problem``
    reads back to an equal problem; clutches are referenced by ``clutch_file`` when given
    (a relative one as it is: relative to the problem file's folder)."""
    b = problem.body
    body: dict = {"model": b.model}
    if b.phenotypes:
        body["phenotypes"] = [{"name": n, **asdict(ph)} for n, ph in b.phenotypes]
    elif b.model == "anny":
        body["phenotype"] = asdict(b.phenotype)
    else:
        body["rest"] = str(Path(b.rest).resolve())
        body["motions"] = {k: str(Path(v).resolve()) for k, v in b.meshes}
        if b.rig:
            body["rig"] = str(Path(b.rig).resolve())
    motions: dict = {"use": list(problem.motions)}
    if problem.activation:
        motions["activation"] = {m: dict(v) for m, v in problem.activation}
    if problem.user_motions:
        motions["define"] = {
            m.name: {"keyframes": [[{"bone": r.bone, "axis": r.axis if isinstance(r.axis, str) else list(r.axis),
                                     "degrees": r.degrees} for r in kf] for kf in m.keyframes],
                     "description": m.description} for m in problem.user_motions}
    g = problem.garment
    garment: dict = {"subdivision": g.subdivision}
    if g.template:
        garment["template"] = g.template
    else:
        garment["mask"] = str(Path(g.mask).resolve())
        garment["attach"] = list(g.attach)
    out = {"body": body, "motions": motions, "garment": garment, "design": problem.design.flat(),
           "solver": asdict(problem.solver), "materials": _materials(problem.materials)}
    if clutch_file is not None:
        cf = Path(clutch_file)  # a relative one is read from beside the problem file (a run folder's own)
        out["clutches"] = {"file": str(cf if not cf.is_absolute() else cf.resolve())}
    hw = problem.clutch_spec().hardware.to_dict()
    if hw:  # written only when not the default, so earlier runs' files and hashes stay as they were
        out.setdefault("clutches", {}).update(hw)
    return out


def _materials(m: MaterialSpec) -> dict:
    """[materials] as written: skin_friction only where set, so that the files (and hashes)
    of problems without it stay as they were."""
    out = asdict(m)
    if not m.skin_friction:
        out.pop("skin_friction")
    return out
