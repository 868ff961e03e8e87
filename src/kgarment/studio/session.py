"""Studio sessions on disk, and opening whatever the user points the studio at.

A session is a folder that every kgarment command can read piece by piece::

    studio.toml        format = "kgarment.studio", version = 1, the page's settings
    problem.toml       the problem (a normal problem file; its clutches: file = "clutches.toml")
    clutches.toml      the clutch layout (kgarment.clutch.save_clutches: rest coordinates)
    design.npz         the manual design: design (m,) 1.0 / 1e-3 (kgarment simulate --design)
    attachments.npz    attached (m,) bool: the painted attachment layer
    compare.npz        design B for comparisons (optional): design (m,), label
    results.json       the last simulation results shown in the page (optional)

Problem files cannot say which single faces are attached (only which boundary rings), so
painted attachments live in attachments.npz; runs started from the studio hold one too
(written by the run driver, which reads it back on ``kgarment design --resume``).
Every file is written atomically; a folder holding anything but a session is refused.
"""

from __future__ import annotations

import dataclasses
import json
import re
import tomllib
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np
import tomli_w

from kgarment.body import Body
from kgarment.case.values import design_values
from kgarment.clutch import save_clutches
from kgarment.design import load_design_history
from kgarment.design.run import final_iteration
from kgarment.errors import KgarmentError
from kgarment.garment import Garment
from kgarment.io import atomic_save_npz, atomic_write_text, json_text
from kgarment.problem import (
    Problem,
    build_body,
    build_garment,
    load_problem,
    override,
    problem_to_dict,
)
from kgarment.studio.state import StudioState

FORMAT = "kgarment.studio"
VERSION = 1
SESSION_FILE = "studio.toml"


class DesignB(NamedTuple):
    """The design compared with the edited one: label (shown in the page) and design (m,) bool."""

    label: str
    design: np.ndarray


@dataclass(frozen=True)
class Opened:
    """What a path given to the studio holds, before the body is built.

    kind : "default" | "problem" | "session" | "run"; problem : Problem;
    design, attached : (m,) arrays or None; compare : design B or None;
    session : the folder Save writes to by default (None: ask); run : a run folder to show;
    settings : the page settings saved with a session; results : saved result rows.
    """

    kind: str
    problem: Problem
    design: np.ndarray | None = None
    attached: np.ndarray | None = None
    compare: DesignB | None = None
    session: Path | None = None
    run: Path | None = None
    settings: dict = field(default_factory=dict)
    results: dict = field(default_factory=dict)

    def with_overrides(self, **changes) -> Opened:
        """This source with command-line overrides of its problem (the keywords of
        :func:`kgarment.problem.override`; None keeps the file's).  The garment of a session
        or run that holds a design or attachments cannot change: those are per face."""
        problem = override(self.problem, **changes)
        per_face = self.design is not None or self.attached is not None
        if problem.garment != self.problem.garment and self.kind in ("session", "run") and per_face:
            raise KgarmentError(f"--garment/--subdivision cannot change the garment of a {self.kind}: its design "
                                "and attachments are per face; open its problem.toml instead")
        return dataclasses.replace(self, problem=problem)


def build_state(opened: Opened, body: Body | None = None) -> StudioState:
    """The :class:`~kgarment.studio.state.StudioState` of an opened source: builds (or
    reuses ``body``, when it is posed in every motion of the problem) the body and garment."""
    problem = opened.problem
    if problem.body.phenotypes:
        raise KgarmentError(f"the studio edits a garment on one body; this problem has {len(problem.body.names)} "
                            f"wearers ([body] phenotypes: {', '.join(problem.body.names)}): open one wearer's "
                            "problem ([body] phenotype = {...}), or design and evaluate the size range with "
                            "kgarment design / sizes / evaluate")
    if body is None or not set(problem.motions) <= set(body.motion_names):
        body = build_body(problem)
    garment = build_garment(problem, body)
    return StudioState(problem, body, garment, design=opened.design, attached=opened.attached)


def is_session(path) -> bool:
    return (Path(path) / SESSION_FILE).is_file()


def is_run(path) -> bool:
    p = Path(path)
    return (p / "problem.toml").is_file() and ((p / "designs.npz").is_file() or (p / "checkpoint.npz").is_file())


def read_source(path=None) -> Opened:
    """Read a problem file, a session folder (or its studio.toml), or a run folder."""
    if path is None:
        return Opened("default", Problem())
    p = Path(path)
    if p.is_file() and p.name == SESSION_FILE:
        p = p.parent
    if p.is_dir():
        if is_session(p):
            return load_session(p)
        if is_run(p):
            return _read_run(p)
        raise KgarmentError(f"{p} is neither a studio session (no {SESSION_FILE}) nor a run folder "
                            "(no problem.toml with designs.npz)")
    if not p.exists():
        raise KgarmentError(f"not found: {p} (give a problem file, a run folder or a studio session)")
    return Opened("problem", load_problem(p))


def _read_run(run: Path) -> Opened:
    problem = load_problem(run / "problem.toml")
    design = None
    if (run / "designs.npz").is_file():
        hist = load_design_history(run)
        design = hist[final_iteration(run)] if len(hist) else None  # the run's final design
    attached = _load_mask(run / "attachments.npz", "attached") if (run / "attachments.npz").is_file() else None
    return Opened("run", problem, design, attached, run=run)


def _load_mask(path: Path, key: str) -> np.ndarray:
    try:
        with np.load(path) as z:
            return np.asarray(z[key])
    except (OSError, ValueError, KeyError, zipfile.BadZipFile) as exc:  # damaged or foreign: one line
        raise KgarmentError(f"cannot read {key} from {path}: {exc}") from None


def load_session(folder) -> Opened:
    """Read a session folder written by :func:`save_session`."""
    folder = Path(folder)
    meta_path = folder / SESSION_FILE
    try:
        meta = tomllib.loads(meta_path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise KgarmentError(f"{meta_path} is not a valid studio session file: {exc}") from None
    if meta.get("format") != FORMAT:
        raise KgarmentError(f"{meta_path}: field 'format' is {meta.get('format')!r}, expected {FORMAT!r}")
    if meta.get("version") != VERSION:
        raise KgarmentError(f"{meta_path}: field 'version' is {meta.get('version')!r}, this studio reads {VERSION}")
    problem = load_problem(folder / meta.get("problem", "problem.toml"))
    design = _load_mask(folder / meta["design"], "design") if meta.get("design") else None
    attached = _load_mask(folder / meta["attachments"], "attached") if meta.get("attachments") else None
    compare = None
    if meta.get("compare"):
        with np.load(folder / meta["compare"]) as z:
            compare = DesignB(str(z["label"]) if "label" in z.files else "B", np.asarray(z["design"]) > 0.5)
    results = {}
    if (folder / "results.json").is_file():
        try:
            results = json.loads((folder / "results.json").read_text())
        except ValueError:
            results = {}
    run = Path(meta["run"]) if meta.get("run") else None
    return Opened("session", problem, design, attached, compare, folder, run,
                  dict(meta.get("settings", {})), results)


def problem_document(problem: Problem, has_clutches: bool) -> dict:
    """A problem as a TOML-ready dict whose clutches are the session's ``clutches.toml``
    (relative, so the folder can move); an explicit empty list when there are none."""
    doc = problem_to_dict(problem)
    hardware = doc.get("clutches", {})  # the clutch hardware, where not the default
    doc["clutches"] = {**hardware, **({"file": "clutches.toml"} if has_clutches else {"clutch": []})}
    return doc


def save_session(state: StudioState, folder, settings: dict | None = None, compare: DesignB | None = None,
                 results: dict | None = None, run: Path | None = None) -> list[Path]:
    """Write ``state`` and the page's extras into a session folder.

    compare : design B (label, (m,) bool) or None; results : JSON-ready result rows;
    run : the run folder shown in the page. Returns the written paths.
    """
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise KgarmentError(f"cannot save a session into {folder}: it is a file")
    if folder.is_dir() and any(folder.iterdir()) and not is_session(folder):
        raise KgarmentError(f"{folder} holds other files; save the session into a new or empty folder")
    folder.mkdir(parents=True, exist_ok=True)
    with state.lock:
        design, attached, specs = state.design.copy(), state.attached.copy(), list(state.clutches)
        problem, garment = state.problem, state.base_garment
        topo, marks = state.topology, state.landmarks
        revision = state.revision
    written = []
    cfile = folder / "clutches.toml"
    if specs:
        tmp = folder / "clutches.tmp.toml"
        save_clutches(tmp, specs, garment.rest_vertices, garment.faces, topology=topo, landmarks=marks)
        tmp.replace(cfile)
        written.append(cfile)
    elif cfile.exists():
        cfile.unlink()
    atomic_write_text(folder / "problem.toml", tomli_w.dumps(problem_document(problem, bool(specs))))
    written.append(folder / "problem.toml")
    atomic_save_npz(folder / "design.npz", design=design_values(design), reinforced=design)
    atomic_save_npz(folder / "attachments.npz", attached=attached)
    written += [folder / "design.npz", folder / "attachments.npz"]
    meta = {"format": FORMAT, "version": VERSION, "problem": "problem.toml", "design": "design.npz",
            "attachments": "attachments.npz", "settings": _toml_safe(settings or {})}
    if compare is not None:
        label, d = compare
        atomic_save_npz(folder / "compare.npz", design=design_values(d), label=np.array(label))
        meta["compare"] = "compare.npz"
        written.append(folder / "compare.npz")
    if results:
        atomic_write_text(folder / "results.json", json_text(results))
        written.append(folder / "results.json")
    if run is not None:
        meta["run"] = str(Path(run).resolve())
    atomic_write_text(folder / SESSION_FILE, tomli_w.dumps(meta))
    written.append(folder / SESSION_FILE)
    with state.lock:
        if state.revision == revision:  # nothing changed while writing
            state.mark_saved()
    return written


def _toml_safe(d: dict) -> dict:
    out = {}
    for k, v in d.items():
        if v is None:
            continue
        if isinstance(v, dict):
            out[str(k)] = _toml_safe(v)
        elif isinstance(v, (list, tuple)):
            out[str(k)] = [x for x in v if x is not None]
        elif isinstance(v, (np.floating, np.integer, np.bool_)):
            out[str(k)] = v.item()
        else:
            out[str(k)] = v
    return out


NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,99}")


def studio_path(root, name: str, what: str, suffix: str = "") -> Path:
    """Where a file or folder the page names goes: ``root / name`` for a plain ``name``
    (letters, digits, '.', '_', '-'; no folders, no '..'), with ``suffix`` appended when
    missing.  The page never chooses where on the disk it writes: only a name under the
    folder given on the command line (what it reads: :mod:`kgarment.studio.folders`)."""
    text = name.strip()
    if not NAME.fullmatch(text) or ".." in text:
        raise KgarmentError(f"{what} {name!r}: give a plain name (letters, digits, '.', '_', '-'); "
                            f"the studio writes it under {root}")
    return Path(root) / (text if not suffix or text.endswith(suffix) else text + suffix)


def export_design(path, design: np.ndarray, garment: Garment, iteration: int | None = None) -> Path:
    """Write a design (m,) bool as an NPZ that ``kgarment simulate --design`` reads:
    design (m,) 1.0 / X_MIN, plus the garment's faces and rest vertices for reference."""
    path = Path(path)
    d = np.asarray(design, bool)
    if d.shape != (garment.n_faces,):
        raise KgarmentError(f"the design has {d.size} faces, the garment {garment.n_faces}")
    extra = {} if iteration is None else {"iteration": np.array(iteration)}
    atomic_save_npz(path, design=design_values(d), faces=garment.faces,
                    rest_vertices=garment.rest_vertices, **extra)
    return path
