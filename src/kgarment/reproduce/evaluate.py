"""Evaluations of the reproduction, cached on disk.

:class:`CachedEvaluator` builds an experiment's problem once (body, garment, clutches)
and evaluates designs with the one design evaluator
(:class:`kgarment.design.Evaluator`), always with the clutches ON and OFF whatever the
problem's objective.  Results are cached in a JSON file keyed by the experiment, a hash of
the built problem (its fields and its clutches as laid) and a hash of the design, so an
interrupted ``reproduce`` picks up where it stopped and a changed problem is not served
stale numbers.  Below that, every solve the evaluations make is kept in the reproduction
folder's ``runs/equilibria/`` (:mod:`kgarment.case.store`): an evaluation or a force over
the motion interrupted half way (the long sleeve's paths take an hour or more at the
default resolution) goes on from the solves it had done, reading them back to the last digit.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
from pathlib import Path

import numpy as np

from kgarment.case.store import FOLDER, EquilibriumStore
from kgarment.constants import SIM_MODEL
from kgarment.evaluate import Evaluator
from kgarment.io import atomic_write_text
from kgarment.problem import Problem, build_body, build_clutches, build_garment, problem_to_dict

log = logging.getLogger(__name__)


class EvaluationCache:
    """A JSON file of evaluation results, rewritten atomically after every addition."""

    def __init__(self, path: Path):
        self.path = Path(path)
        self.data = json.loads(self.path.read_text()) if self.path.is_file() else {}

    def get(self, key: str):
        return self.data.get(key)

    def put(self, key: str, value) -> None:
        self.data[key] = value
        atomic_write_text(self.path, json.dumps(self.data, indent=1))


def design_key(design: np.ndarray) -> str:
    """A short hash of which faces a design (m,) reinforces."""
    return hashlib.sha1(np.packbits(np.asarray(design) > 0.5).tobytes()).hexdigest()[:16]


def problem_key(problem: Problem, strips) -> str:
    """A short hash of a built problem: its fields, its clutch strips as laid, and the
    simulation model's version (an evaluation cached under other physics is not reused)."""
    h = hashlib.sha1(json.dumps(problem_to_dict(problem), sort_keys=True, default=str).encode())
    h.update(f"sim_model {SIM_MODEL}".encode())
    for s in strips:
        h.update(f"{s.name}|{s.length:.9g}|{s.width:.9g}|{s.prestrain:.9g}".encode())
        h.update(np.ascontiguousarray(s.bind_face).tobytes())
    return h.hexdigest()[:12]


class CachedEvaluator:
    """Evaluates designs on ``problem``'s motions with its clutches ON and OFF.

    problem : Problem (its objective and its balance are ignored: states are ON and OFF, and
    with a lockout the lock states);  name : the key of
    this problem in the cache;  cache : EvaluationCache or None.  ``body``, ``garment``,
    ``strips`` and ``case`` are the built problem (for renders and baselines).
    """

    def __init__(self, problem: Problem, name: str, cache: EvaluationCache | None = None, device: str = "cpu"):
        self.cache = cache
        problem = dataclasses.replace(problem, design=dataclasses.replace(problem.design, balance=0.0))
        self.problem = problem
        self.body = build_body(problem)
        self.garment = build_garment(problem, self.body)
        self.strips = build_clutches(problem, self.body, self.garment)
        self.label = name  # in progress lines
        self.name = f"{name}#{problem_key(problem, self.strips)}"
        store = None if cache is None else EquilibriumStore(cache.path.parent / "runs" / FOLDER)
        self.evaluator = Evaluator.from_problem(problem, body=self.body, garment=self.garment, strips=self.strips,
                                                device=device, objective="active", store=store)
        self.case = self.evaluator.case
        self._paths: dict = {}  # (design key, frames) -> PathReport (:meth:`_path_report`)

    @property
    def motions(self) -> list[str]:
        return self.evaluator.motions

    @property
    def n_states(self) -> int:
        return len(self.case.states())

    def evaluate(self, design: np.ndarray, label: str = "", loads: bool = False) -> dict:
        """rho ON/OFF per motion and the structural metrics of ``design`` (m,) (and with
        ``loads`` the per-clutch loads): :meth:`kgarment.design.DesignEvaluation.to_json`
        with ``label``."""
        design = np.asarray(design, dtype=np.float64)
        key = f"{self.name}|{design_key(design)}" + ("|loads2" if loads else "")  # loads2: with needed
        if self.cache is not None and (hit := self.cache.get(key)) is not None:
            return hit
        out = {"label": label, **self.evaluator.evaluate(design, loads=loads).to_json()}
        if self.cache is not None:
            self.cache.put(key, out)
        return out

    def evaluate_with_path(self, design: np.ndarray, label: str, frames: int, loads: bool = True) -> tuple[dict, dict]:
        """(evaluation, with ``loads`` the per-clutch loads; force over the motion) of
        ``design`` (m,): the motion solved from rest in ``frames`` frames first, its last
        frames then competing with the evaluation's two starts
        (:meth:`kgarment.design.Evaluator.evaluate`'s ``known``), so the report's rho, loads
        and force curves are of the equilibrium the wearer reaches where it is the lower.
        Both cached like the evaluations."""
        design = np.asarray(design, dtype=np.float64)
        key = f"{self.name}|{design_key(design)}" + ("|loads2" if loads else "") + f"|path{frames}"
        pkey = self._path_key(design, frames)
        if self.cache is not None and (hit := self.cache.get(key)) is not None \
                and (phit := self.cache.get(pkey)) is not None:
            return hit, self._with_rest(design, pkey, phit)
        path = self._path_report(design, frames, label)
        out = {"label": label, **self.evaluator.evaluate(design, loads=loads, known=path.ends).to_json()}
        frames_json = path.to_json()
        if self.cache is not None:
            self.cache.put(pkey, frames_json)
            self.cache.put(key, out)
        return out, frames_json

    def _with_rest(self, design: np.ndarray, key: str, doc: dict) -> dict:
        """A cached path JSON ``doc`` made before paths had their rest frame (t = 0), or
        had it from fewer starts (``rest_starts`` below :data:`~kgarment.evaluate.path.REST_STARTS`): the
        rest frames solved now (:func:`kgarment.evaluate.path.rest_frames`, the first frame
        solved again for its backward start: seconds) and added, the summary's work taken
        from them, and stored under ``key`` again; the frames of the motion (minutes) stay
        those cached."""
        from kgarment.evaluate.path import REST_STARTS, PathReport, rest_frames

        if doc.get("rest_starts") == REST_STARTS:
            return doc

        motions = list(dict.fromkeys(f["motion"] for f in doc["frames"]))
        frames = round(1.0 / min(f["t"] for f in doc["frames"] if f["t"] > 0.0))
        rest = rest_frames(self.evaluator, np.asarray(design, dtype=np.float64), self.problem, motions, frames)
        out = PathReport.from_json(doc).with_rest(rest).to_json()
        if self.cache is not None:
            self.cache.put(key, out)
        return out

    def _path_key(self, design: np.ndarray, frames: int) -> str:
        return f"{self.name}|{design_key(design)}|path{frames}|v2"  # v2: the end anchored at the target's equilibrium

    def _path_report(self, design: np.ndarray, frames: int, label: str = ""):
        """:func:`kgarment.evaluate.path.path_forces` of ``design`` (m,) (``label``: its name in
        the progress lines), kept for this object's life (its ends serve the evaluation and
        the control table of the same design)."""
        from kgarment.evaluate.path import path_forces

        k = (design_key(design), frames)
        if k not in self._paths:  # minutes at the default resolution: each frame logged, with its ETA
            self._paths[k] = path_forces(self.evaluator, design, self.problem, frames=frames,
                                         report=lambda line: log.info("%s, %s, the force over the motion: %s",
                                                                      self.label, label or "design", line))
        return self._paths[k]

    def plan(self, design: np.ndarray, frames: int = 0) -> dict:
        """The control table of ``design`` (m,) (:func:`kgarment.evaluate.plan.make_plan`: every
        clutch set in every motion) as JSON, cached like the evaluations; with ``frames`` the
        motion from rest in that many frames first, its ends competing with the two starts
        (``make_plan``'s ``known``) as in :meth:`evaluate_with_path`."""
        from kgarment.evaluate.plan import make_plan

        design = np.asarray(design, dtype=np.float64)
        key = f"{self.name}|{design_key(design)}|plan" + (f"|path{frames}" if frames else "")
        if self.cache is not None and (hit := self.cache.get(key)) is not None:
            return hit
        known = self._path_report(design, frames).ends if frames else None
        out = make_plan(self.evaluator, design, known=known).to_json()
        if self.cache is not None:
            self.cache.put(key, out)
        return out

    def path(self, design: np.ndarray, frames: int, label: str = "") -> dict:
        """The force over the motion of ``design`` (m,) in ``frames`` frames, ON and OFF
        (:func:`kgarment.evaluate.path.path_forces`) as JSON, cached like the evaluations
        (``label``: the design's name in the progress lines)."""
        design = np.asarray(design, dtype=np.float64)
        key = self._path_key(design, frames)
        if self.cache is not None and (hit := self.cache.get(key)) is not None:
            return self._with_rest(design, key, hit)
        out = self._path_report(design, frames, label).to_json()
        if self.cache is not None:
            self.cache.put(key, out)
        return out
