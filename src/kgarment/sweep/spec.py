"""Sweep files: a base problem and its variations, expanded into tasks and validated
before anything runs.

A sweep file (TOML)::

    example = "shirt_three_motions"       # the base problem: an example by name,
    # problem = "my_problem.toml"         #   or a problem file (relative to the sweep file),
    # [problem] ...                       #   or an inline problem table
    [set]                                 # fields set in every task (optional)
    "garment.subdivision" = 0
    [grid]                                # axes: the tasks are their cartesian product
    "design.target_area" = [0.10, 0.15, 0.20]
    "body.phenotype.weight" = [0.3, 0.7]
    # or instead of [grid], a list of runs, each a name and its fields:
    # [[runs]]
    # name = "reference"
    # "materials.preset" = "reference"

Fields are problem-file fields (:mod:`kgarment.problem.parse`) written as dotted paths
(``"design.target_area"``) or as nested tables (``design = { target_area = [...] }``); the
first level of a dotted key is split at its dots, so a name holding dots (a motion such as
``arm_flexion.right``) is written as a quoted part of a TOML dotted key
(``motions.activation."arm_flexion.right"``).  A number as a part indexes an array of
tables (``"clutches.clutch.0.length"``).  A task's problem is the base with ``[set]`` and
its own values set, field by field, and ``[solver] workers = 1`` (each task runs in one
process on one thread; the sweep runs tasks side by side).  Every task's problem is
validated with :func:`kgarment.problem.parse_problem` before any task runs; a bad field or
value is one :class:`~kgarment.errors.KgarmentError` naming the axis (or the task) and what
is allowed.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path

from kgarment.errors import KgarmentError
from kgarment.io import read_toml
from kgarment.problem import Problem, example_path, parse_problem

SWEEP_KEYS = ("problem", "example", "set", "grid", "runs")
NAME_CHARS = re.compile(r"[^A-Za-z0-9._=,+-]")
NAME_OK = re.compile(r"[A-Za-z0-9][A-Za-z0-9._=,+-]*")
MAX_NAME = 100  # characters of a task's folder name
FORCED = {("solver", "workers"): 1}  # each task: one process (the sweep runs tasks in parallel)
# problem fields holding file paths (made absolute in a task's problem, so that its file
# reads the same from anywhere): (path, whether the field is a table of paths)
PATH_FIELDS = ((("body", "rest"), False), (("body", "rig"), False), (("body", "motions"), True),
               (("garment", "mask"), False), (("clutches", "file"), False))

@dataclass(frozen=True)
class Task:
    """One variation: its folder name, its axis values ((label, value), ...; label the
    dotted field path), its problem as a TOML dict (paths absolute, ``[solver] workers =
    1``) and that problem validated."""

    name: str
    values: tuple[tuple[str, object], ...]
    data: dict
    problem: Problem


@dataclass(frozen=True)
class Sweep:
    """A parsed sweep file: its path and text, the base's folder (relative paths of the
    base problem), what the base is (for messages), the axes (dotted labels, in order; a
    list of runs has the union of its fields) and the tasks."""

    path: Path
    text: str
    base_dir: Path
    base: str
    axes: tuple[str, ...]
    tasks: tuple[Task, ...]


def label(path: tuple) -> str:
    """A field path as written in a sweep file: ``design.target_area``; a part holding a
    dot is quoted (``motions.activation."arm_flexion.right"``)."""
    return ".".join(f'"{p}"' if "." in str(p) else str(p) for p in path)


def load_sweep(path) -> Sweep:
    """Read, expand and validate a sweep file (every task's problem; errors name the field)."""
    path = Path(path)
    if not path.is_file():
        raise KgarmentError(f"sweep file not found: {path}")
    text, doc = read_toml(path, "sweep file")
    where = f"sweep file {path}"
    bad = sorted(set(doc) - set(SWEEP_KEYS))
    if bad:
        raise KgarmentError(f"{where}: unknown field {bad[0]!r}; allowed: {', '.join(SWEEP_KEYS)}")
    base, base_dir, source, what = _base(doc, path)
    common = fields(doc.get("set", {}), f"{where} [set]")
    data = _apply(base, common, f"{where}: the base problem ({what}) with [set]")
    _validate(data, base_dir, source, f"{where}: the base problem ({what})" + (" with [set]" if common else ""))
    if ("grid" in doc) == ("runs" in doc):
        raise KgarmentError(f"{where}: give the variations as [grid] (axes: field = [values]) or as [[runs]] "
                            "(each a name and its fields), one of them")
    if "grid" in doc:
        axes, variations = _grid(doc["grid"], where, data, base_dir, source)
    else:
        axes, variations = _runs(doc["runs"], where)
    tasks, seen = [], {}
    for name, values, what_task in variations:
        here = f"{where} {what_task}"
        task_data = _apply(data, values, here)
        for p, v in FORCED.items():
            _set(task_data, p, v, here)
        if name is None:
            name = task_name(values, axes)
        if name in seen:
            raise KgarmentError(f"{where}: two tasks are named {name!r} ({seen[name]} and {what_task}); "
                                "give every run its own name")
        seen[name] = what_task
        problem = _validate(task_data, base_dir, source, f"{where}: task {name!r}")
        tasks.append(Task(name, tuple((label(p), v) for p, v in values), _absolute(task_data, base_dir), problem))
    return Sweep(path, text, base_dir, what, tuple(label(p) for p in axes), tuple(tasks))


def _base(doc: dict, path: Path) -> tuple[dict, Path, Path | None, str]:
    """(problem dict, folder its relative paths start from, its file or None, a description)."""
    where = f"sweep file {path}"
    given = [k for k in ("problem", "example") if k in doc]
    if len(given) != 1:
        raise KgarmentError(f"{where}: give one base problem: problem = \"FILE.toml\" (relative to the sweep file), "
                            "example = \"NAME\" (kgarment examples) or an inline [problem] table")
    if given == ["example"]:
        if not isinstance(doc["example"], str):
            raise KgarmentError(f"{where}: example = {doc['example']!r} must be an example's name (kgarment examples)")
        try:
            file = example_path(doc["example"])
        except KgarmentError as exc:
            raise KgarmentError(f"{where}: {exc}") from None
        return _read_problem(file, where), file.parent, file, f"example {doc['example']}"
    p = doc["problem"]
    if isinstance(p, dict):
        return copy.deepcopy(p), path.parent.resolve(), None, "the inline [problem]"
    if not isinstance(p, str):
        raise KgarmentError(f"{where}: problem = {p!r} must be a problem file's path or a [problem] table")
    file = Path(p) if Path(p).is_absolute() else path.parent / p
    if not file.is_file():
        raise KgarmentError(f"{where}: problem file not found: {file}")
    return _read_problem(file, where), file.parent.resolve(), file.resolve(), f"problem {p}"


def _read_problem(file: Path, where: str) -> dict:
    try:
        return read_toml(file, "problem file")[1]
    except KgarmentError as exc:
        raise KgarmentError(f"{where}: {exc}") from None


def fields(table, where: str) -> list[tuple[tuple, object]]:
    """A sweep table's (field path, value) pairs: nested tables are walked down to their
    values; a first-level key is split at its dots."""
    if not isinstance(table, dict):
        raise KgarmentError(f"{where} must be a table of fields (\"section.field\" = value)")
    out: list = []

    def walk(prefix: tuple, d: dict) -> None:
        for k, v in d.items():
            p = prefix + (tuple(k.split(".")) if not prefix else (k,))
            if any(not part for part in p):
                raise KgarmentError(f"{where}: field {k!r} has an empty part; write section.field")
            if isinstance(v, dict) and v:
                walk(p, v)
            else:
                out.append((p, v))

    walk((), table)
    return out


def _grid(table, file: str, data: dict, base_dir: Path, source) -> tuple[list, list]:
    """[grid] -> (axes, variations: (None, values, what)): each axis's values checked alone
    on the base first, so that a bad value is named by its axis; the variations are the
    cartesian product."""
    where = f"{file} [grid]"
    axes = fields(table, where)
    if not axes:
        raise KgarmentError(f"{where} has no axis; give at least one: \"section.field\" = [value, ...]")
    for p, values in axes:
        if not isinstance(values, list):
            raise KgarmentError(f"{where} \"{label(p)}\" = {values!r} must be a list of values (an axis); "
                                "fields with one value go into [set]")
        if not values:
            raise KgarmentError(f"{where} \"{label(p)}\" = [] is empty; give at least one value")
        if len({_key(v) for v in values}) != len(values):
            raise KgarmentError(f"{where} \"{label(p)}\" lists a value more than once: {values!r}")
        _forced(p, f"{where} \"{label(p)}\"")
        for v in values:
            here = f"{where} \"{label(p)}\" = {v!r}"
            _validate(_apply(data, [(p, v)], here), base_dir, source, here)
    variations = []
    for combo in itertools.product(*(values for _, values in axes)):
        values = [(p, v) for (p, _), v in zip(axes, combo)]
        variations.append((None, values, "[grid] " + ", ".join(f"\"{label(p)}\" = {v!r}" for p, v in values)))
    return [p for p, _ in axes], variations


def _runs(runs, file: str) -> tuple[list, list]:
    """[[runs]] -> (axes: every field some run sets, in order; variations: (name or None,
    values, what))."""
    where = f"{file} [[runs]]"
    if not isinstance(runs, list) or not runs or not all(isinstance(r, dict) for r in runs):
        raise KgarmentError(f"{where} must be a non-empty list of tables: [[runs]] name = \"...\" and fields")
    axes: list = []
    variations = []
    for k, run in enumerate(runs):
        run = dict(run)
        name = run.pop("name", None)
        what = f"[[runs]] #{k + 1}" + (f" ({name!r})" if isinstance(name, str) else "")
        here = f"{file} {what}"
        if name is not None and (not isinstance(name, str) or not NAME_OK.fullmatch(name) or len(name) > MAX_NAME):
            raise KgarmentError(f"{here}: name = {name!r} must be a folder name: letters, digits and . _ = , + - "
                                f"(not first), at most {MAX_NAME} characters")
        values = fields(run, here)
        for p, _ in values:
            _forced(p, f"{here} \"{label(p)}\"")
            if p not in axes:
                axes.append(p)
        variations.append((name, values, what))
    return axes, variations


def _forced(p: tuple, where: str) -> None:
    if tuple(p) in FORCED:
        raise KgarmentError(f"{where}: a sweep runs every task in one process ([solver] workers = 1) and tasks "
                            "side by side; give kgarment sweep --workers N instead")


def _key(v) -> str:
    return json.dumps(v, sort_keys=True, default=str)


def _apply(data: dict, values, where: str) -> dict:
    """A deep copy of ``data`` with every (path, value) of ``values`` set."""
    out = copy.deepcopy(data)
    for p, v in values:
        _set(out, p, copy.deepcopy(v), where)
    return out


def _set(data: dict, path: tuple, value, where: str) -> None:
    """Set the field at ``path`` (tables created where missing; a number indexes an
    existing array of tables)."""
    node = data
    for i, part in enumerate(path[:-1]):
        here = label(path[: i + 1])
        if isinstance(node, list):
            node = node[_index(node, part, here, where)]
        elif isinstance(node, dict):
            if part not in node and path[i + 1].isdigit():
                raise KgarmentError(f"{where}: the base problem has no array of tables {here} to index with "
                                    f"{path[i + 1]}")
            node = node.setdefault(part, {})
        if not isinstance(node, (dict, list)):
            raise KgarmentError(f"{where}: {here} = {node!r} in the base problem is a value, not a table; "
                                f"\"{label(path)}\" names no field")
    last = path[-1]
    if isinstance(node, list):
        node[_index(node, last, label(path), where)] = value
    else:
        node[last] = value


def _index(node: list, part: str, here: str, where: str) -> int:
    if not part.isdigit() or int(part) >= len(node):
        raise KgarmentError(f"{where}: {here}: the base problem's array there holds {len(node)} tables; give an "
                            f"index 0..{len(node) - 1}")
    return int(part)


def _validate(data: dict, base_dir: Path, source, where: str) -> Problem:
    """The parsed problem, its [motions.activation] clutch names checked too (a run would refuse them)."""
    from kgarment.case.setup import activation_vectors
    from kgarment.problem.build import clutch_names

    try:
        problem = parse_problem(copy.deepcopy(data), base_dir, source)
        activation_vectors(problem, clutch_names(problem))
        return problem
    except KgarmentError as exc:
        raise KgarmentError(f"{where}: {exc}") from None


def _absolute(data: dict, base_dir: Path) -> dict:
    """``data`` with its relative file paths made absolute (from ``base_dir``)."""
    out = copy.deepcopy(data)
    for (section, key), table in PATH_FIELDS:
        sec = out.get(section)
        if not isinstance(sec, dict) or key not in sec:
            continue
        if table and isinstance(sec[key], dict):
            sec[key] = {k: _abs(v, base_dir) for k, v in sec[key].items()}
        elif not table:
            sec[key] = _abs(sec[key], base_dir)
    return out


def _abs(v, base_dir: Path):
    return str((base_dir / v).resolve()) if isinstance(v, str) and not Path(v).is_absolute() else v


def format_value(v) -> str:
    """A value as it goes into a task name: numbers in their shortest form, lists joined
    with '+'."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:g}" if math.isfinite(v) else str(v)
    if isinstance(v, (list, tuple)):
        return "+".join(format_value(x) for x in v)
    if isinstance(v, dict):
        return "+".join(f"{k}-{format_value(x)}" for k, x in v.items())
    return str(v)


def task_name(values, axes) -> str:
    """A readable, filesystem-safe folder name for a task: ``target_area=0.1,weight=0.3``
    (each field by its last part, or more parts where two axes end alike); ``base`` for
    no values; a long name is cut and given a hash."""
    if not values:
        return "base"
    short = {}
    for p in axes:
        n = 1
        while n < len(p) and any(q != p and tuple(q[-n:]) == tuple(p[-n:]) for q in axes):
            n += 1
        short[tuple(p)] = ".".join(map(str, p[-n:]))
    name = ",".join(f"{short[tuple(p)]}={format_value(v)}" for p, v in values)
    name = NAME_CHARS.sub("_", name).lstrip(".") or "task"
    if len(name) > MAX_NAME:
        name = name[: MAX_NAME - 9] + "-" + hashlib.sha1(name.encode()).hexdigest()[:8]
    return name
