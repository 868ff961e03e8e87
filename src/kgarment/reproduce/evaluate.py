"""Evaluating designs on a problem: rho ON/OFF per motion, islands, clutch junctions.

An :class:`Evaluator` builds a problem once (body, garment, clutches, simulation model),
solves the fully reinforced garment in every state once (the reference of rho), and then
evaluates any design of that garment (the starts: :func:`kgarment.design.driver.design_equilibria`).
Results are cached in a JSON file keyed by the problem and a hash of the design, so an interrupted
``reproduce`` picks up where it stopped.
"""

from __future__ import annotations

import hashlib
import json
import logging
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)


class EvaluationCache:
    """A JSON file of evaluation results, rewritten atomically after every addition."""

    def __init__(self, path: Path):
        self.path = Path(path)
        self.data = json.loads(self.path.read_text()) if self.path.is_file() else {}

    def get(self, key: str):
        return self.data.get(key)

    def put(self, key: str, value) -> None:
        from kgarment.design.run import atomic_write_text

        self.data[key] = value
        atomic_write_text(self.path, json.dumps(self.data, indent=1))


def design_key(design: np.ndarray) -> str:
    """A short hash of which faces a design (m,) reinforces."""
    return hashlib.sha1(np.packbits(np.asarray(design) > 0.5).tobytes()).hexdigest()[:16]


class Evaluator:
    """Evaluates designs on ``problem``'s motions with its clutches ON and OFF.

    problem : kgarment.problem.Problem (its objective is ignored: states are ON and OFF);
    name : the key of this problem in the cache;  cache : EvaluationCache or None.
    """

    def __init__(self, problem, name: str, cache: EvaluationCache | None = None, device: str = "cpu"):
        import dataclasses

        from kgarment.design.driver import build_setup
        from kgarment.problem import build_body, build_clutches, build_garment

        self.problem = dataclasses.replace(problem, design=dataclasses.replace(problem.design, objective="active"))
        self.name = name
        self.cache = cache
        self.body = build_body(self.problem)
        self.garment = build_garment(self.problem, self.body)
        self.strips = build_clutches(self.problem, self.body, self.garment)
        self.setup = build_setup(self.problem, self.body, self.garment, self.strips, device, evaluation=True)
        self.keyed = self.setup.states()
        self._full = None

    @property
    def motions(self) -> list[str]:
        return list(self.setup.motions)

    @property
    def n_faces(self) -> int:
        return self.garment.n_faces

    def full(self):
        """The fully reinforced garment's equilibria (solved once)."""
        if self._full is None:
            from kgarment.sim import solve_states

            self._full = solve_states(self.setup.model, np.ones(self.n_faces), [s for _, s in self.keyed],
                                      options=self.setup.solver)
        return self._full

    def evaluate(self, design: np.ndarray, label: str = "") -> dict:
        """rho ON/OFF per motion and the structural metrics of ``design`` (m,).

        Returns {"rho": {motion: {"on": float, "off": float}}, "islands": int,
        "islands_with_clutches": int, "clutch_ends_supported": int, "clutch_ends": int,
        "area": float (share of the rest area), "converged": bool, "label": str}.
        """
        from kgarment.design.driver import design_equilibria
        from kgarment.design.metrics import (
            Stored,
            clutch_end_support,
            islands,
            relative_energy_density,
        )

        design = np.asarray(design, dtype=np.float64)
        if len(design) != self.n_faces:
            raise ValueError(f"design has {len(design)} faces, the garment of {self.name} {self.n_faces}")
        key = f"{self.name}|{design_key(design)}"
        if self.cache is not None and (hit := self.cache.get(key)) is not None:
            return hit
        full = self.full()
        mine = design_equilibria(self.setup, design, self.full)
        setup = self.setup
        rho: dict = {}
        for ((motion, state), _), rf, rd in zip(self.keyed, full, mine):
            sf, sd = Stored.of(rf), Stored.of(rd)
            rho.setdefault(motion, {})[state] = relative_energy_density(design, setup.areas, sd, sf,
                                                                        setup.clutch_area())
        ends = clutch_end_support(design, setup.end_faces)
        faces = self.garment.faces
        out = {
            "label": label, "rho": rho,
            "islands": islands(faces, design, adjacency=setup.adjacency),
            "islands_with_clutches": islands(faces, design, links=setup.end_faces, adjacency=setup.adjacency),
            "clutch_ends_supported": int(sum(a + b for a, b in ends)), "clutch_ends": 2 * len(ends),
            "area": float(setup.areas[design > 0.5].sum() / setup.areas.sum()),
            "converged": bool(all(r.converged for r in full) and all(r.converged for r in mine)),
        }
        if self.cache is not None:
            self.cache.put(key, out)
        return out
