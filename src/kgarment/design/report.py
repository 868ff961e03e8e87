"""The pictures and files at the end of a design run."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from kgarment.case.keys import Kind, parse_label
from kgarment.case.values import design_values
from kgarment.design.run import progress_plot
from kgarment.io import atomic_save_npz, atomic_write_bytes, atomic_write_text, write_ply
from kgarment.render import faces_near, render_design, render_scene

log = logging.getLogger(__name__)
REINFORCED = (0.15, 0.20, 0.45, 1.0)
SOFT = (0.80, 0.85, 0.95, 1.0)


def design_colors(design: np.ndarray) -> np.ndarray:
    """(m, 4) RGBA: dark for reinforced faces, light for plain cloth."""
    return np.where((design > 0.5)[:, None], REINFORCED, SOFT)


def write_design_mesh(path, vertices, faces, design) -> Path:
    """PLY (and OBJ beside it) of the garment with per-face colours of the design."""
    import trimesh

    mesh = trimesh.Trimesh(vertices, faces, process=False, face_colors=(design_colors(design) * 255).astype(np.uint8))
    mesh.face_attributes["design"] = np.asarray(design, dtype=np.float64)
    path = atomic_write_bytes(path, trimesh.exchange.ply.export_ply(mesh, include_attributes=True))
    atomic_write_text(path.with_suffix(".obj"), trimesh.exchange.obj.export_obj(mesh, include_color=True))
    return path


def finish_run(run: Path, setup, st, body, garment, strips, iteration: int, equilibria=None) -> list[Path]:
    """Final design (NPZ, PLY, OBJ: the design of ``iteration``), progress plot, and renders of
    it coloured by energy density for each motion and state (one colour scale per motion,
    ON and OFF alike). ``equilibria``: {(motion, state): StateResult} of the final design (the
    evaluation's); without them the states are solved from the run's last equilibria.
    Returns the written paths."""
    final = run / "final"
    final.mkdir(exist_ok=True)
    design = design_values(st.designs[iteration])
    paths = [progress_plot(run, st.metrics)]
    atomic_save_npz(final / "design.npz", design=design, faces=garment.faces, rest_vertices=garment.rest_vertices,
                    iteration=np.array(iteration))
    paths.append(final / "design.npz")
    paths.append(write_design_mesh(final / "design.ply", garment.rest_vertices, garment.faces, design))
    # pictures framed on the garment (within 5 cm of it): a sleeve is a small part of the body
    paths.append(render_design(final / "design.png", body.rest_vertices,
                               faces_near(body.rest_vertices, body.faces, garment.rest_vertices), garment.rest_vertices,
                               garment.faces, design, clutches=[(c.vertices, c.faces) for c in strips],
                               title=f"{garment.name}: final design (iteration {iteration})"))
    # the motions the body is posed in (and a multi-body design's wearers): not the
    # beginnings of motions that [design] early adds to the objective
    keyed = [(k, s) for k, s in setup.case.states() if k[0] in setup.case.wearers or k[0] in body.motion_names]
    if equilibria is None or any(k not in equilibria for k, _ in keyed):
        states = [s for _, s in keyed]
        solved = setup.case.solve(design, states, warm_start=[st.warm.get(s.name) for s in states])
        equilibria = {k: r for (k, _), r in zip(keyed, solved)}
    vmax = {}
    for (motion, _), r in equilibria.items():
        vmax[motion] = max(vmax.get(motion, 0.0), float(np.percentile(r.garment_density, 99)))
    for key, s in keyed:
        r = equilibria[key]
        w = setup.case.wearers.get(key[0])  # a multi-body design's: this motion's body and garment
        on, pose, model = (body, key[0], setup.case.model) if w is None else (w.body, w.motion, w.model)
        gx, cx = model.split(r.x)
        bv = on.vertices(pose)
        paths.append(render_scene(final / f"energy_{key[0]}_{key[1].replace(':', '-')}.png", bv,
                                  faces_near(bv, on.faces, gx), gx, garment.faces, face_values=r.garment_density, vmin=0.0,
                                  vmax=vmax[key[0]], clutches=[(x, c.faces) for c, x in zip(model.clutches, cx)],
                                  clutch_activation=s.activation, value_label="energy density (J/m^2)",
                                  title=f"{garment.name}: {key[0]}, clutches {_state_title(key[1])}"))
    return paths


def write_equilibrium(out: Path, stem: str, body_vertices: np.ndarray, body_faces: np.ndarray, model, result,
                      activation, title: str) -> list[Path]:
    """One equilibrium as files: ``stem.ply`` (garment, per-face energy density J/m^2),
    ``stem_clutch_<name>.ply`` per clutch, and ``stem.png`` coloured by energy density.

    body_vertices : (nb, 3) the posed body, m;  body_faces : (mb, 3);  model : SimModel;
    result : its StateResult;  activation : (K,) clutch activation in [0, 1].
    """
    out = Path(out)
    gx, cx = model.split(result.x)
    paths = [write_ply(out / f"{stem}.ply", gx, model.garment_faces, {"energy_density": result.garment_density})]
    for c, (strip, x) in enumerate(zip(model.clutches, cx)):
        paths.append(write_ply(out / f"{stem}_clutch_{strip.name}.ply", x, strip.faces,
                               {"energy_density": result.clutch_density[c]}))
    paths.append(render_scene(out / f"{stem}.png", body_vertices, body_faces, gx, model.garment_faces,
                              face_values=result.garment_density,
                              clutches=[(x, s.faces) for s, x in zip(model.clutches, cx)],
                              clutch_activation=activation, value_label="energy density (J/m^2)", title=title))
    return paths


def _state_title(state: str) -> str:
    """A state label in words: "on", "off", "as in arms_raise" for a lock state, "upper_back
    only" for a solo state."""
    kind, which = parse_label(state)
    if kind is Kind.LOCK:
        return f"as in {which}"
    return f"{which} only" if kind is Kind.SOLO else state
