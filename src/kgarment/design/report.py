"""The pictures and files at the end of a design run."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from kgarment.design.run import progress_plot
from kgarment.paths import atomic_save_npz

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
    path = Path(path)
    path.write_bytes(trimesh.exchange.ply.export_ply(mesh, include_attributes=True))
    path.with_suffix(".obj").write_text(trimesh.exchange.obj.export_obj(mesh, include_color=True))
    return path


def finish_run(run: Path, setup, st, body, garment, strips) -> list[Path]:
    """Final design (NPZ, PLY, OBJ), progress plot, and renders of the final design
    coloured by energy density for each motion and state. Returns the written paths."""
    from kgarment.render import render_design, render_scene
    from kgarment.sim import solve_states

    final = run / "final"
    final.mkdir(exist_ok=True)
    design = np.where(st.designs[-1], 1.0, setup.params.x_min)
    paths = [progress_plot(run, st.metrics)]
    atomic_save_npz(final / "design.npz", design=design, faces=garment.faces, rest_vertices=garment.rest_vertices,
                    iteration=np.array(len(st.designs) - 1))
    paths.append(final / "design.npz")
    paths.append(write_design_mesh(final / "design.ply", garment.rest_vertices, garment.faces, design))
    paths.append(render_design(final / "design.png", body.rest_vertices, body.faces, garment.rest_vertices,
                               garment.faces, design, clutches=[(c.vertices, c.faces) for c in strips],
                               title=f"{garment.name}: final design"))
    keyed = setup.states()
    states = [s for _, s in keyed]
    results = solve_states(setup.model, design, states, warm_start=[st.warm.get(s.name) for s in states],
                           options=setup.solver)
    vmax = max(float(np.percentile(r.garment_density, 99)) for r in results)
    for (key, s), r in zip(keyed, results):
        gx, cx = setup.model.split(r.x)
        act = s.activation
        paths.append(render_scene(final / f"energy_{key[0]}_{key[1]}.png", body.vertices(key[0]), body.faces, gx,
                                  garment.faces, face_values=r.garment_density, vmin=0.0, vmax=vmax,
                                  clutches=[(x, c.faces) for c, x in zip(setup.model.clutches, cx)],
                                  clutch_activation=act, value_label="energy density (J/m^2)",
                                  title=f"{garment.name}: {key[0]}, clutches {key[1]}"))
    return paths
