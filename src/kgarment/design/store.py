"""Equilibria kept on disk: a run folder's ``equilibria/``, read back by later evaluations.

A design run ends with the evaluation of its final design (the one design evaluator,
:mod:`kgarment.design.evaluate`): every state from two starts, the fully reinforced
garment's states, one state per clutch and motion for the loads.  ``kgarment evaluate RUN``
(with or without ``--path``) and ``kgarment plan RUN`` then need the same equilibria again,
in another process.  The evaluator keeps each equilibrium it solves in the run's
``equilibria/`` folder and takes it from there the next time instead of solving it again,
so a later command gives the same numbers to the last digit (the same equilibria) without
the solves.

An entry is keyed by content, never by name: the simulation model's version
(``SIM_MODEL``), a digest of the simulator's and the evaluator's source files (an entry
written by other code is not used), the solver options, the device, the simulation model
(garment, clutches, materials, clutch model; every array of it), the design's values (for
the design's equilibria), the posed body, the skin-tight garment, its attachments and the
clutch activation (:func:`kgarment.design.evaluate.state_digest`) and what kind of solve
it is (the fully reinforced garment, the design from the two starts, a load state).  A
different clutch model or friction given on the command line, another body or design,
simply finds no entry.  One ``.npz`` file per entry (no pickle: nothing in a run folder is
executed on reading), written to a temporary name and renamed, so a reader never sees half
a file; an unreadable entry is reported and solved again.  Size: about 0.1 MB per state at
subdivision 0 (the main job's run: ~40 states, 4 MB), ~1.3 MB at subdivision 2.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import io
import json
import logging
import os
from pathlib import Path

import numpy as np

from kgarment.constants import SIM_MODEL
from kgarment.sim import StateResult
from kgarment.sim.options import Convergence

log = logging.getLogger(__name__)
FOLDER = "equilibria"  # the store's folder in a run folder
# the sources whose change can change an equilibrium or what an evaluation keeps of it
CODE = ("sim", "design/evaluate.py", "design/loads.py", "design/setup.py", "constants.py")


@functools.cache
def code_digest() -> str:
    """A digest of the simulator's and the evaluator's source files (:data:`CODE`)."""
    root = Path(__file__).resolve().parent.parent
    h = hashlib.blake2b(digest_size=12)
    for part in CODE:
        path = root / part
        for f in sorted(path.rglob("*.py")) if path.is_dir() else [path]:
            h.update(f.relative_to(root).as_posix().encode())
            h.update(f.read_bytes())
    return h.hexdigest()


def content_digest(*objs) -> str:
    """A digest of ``objs``: arrays by dtype, shape and bytes, sparse matrices and tensors
    by their arrays, dataclasses field by field, containers item by item, the rest by repr."""
    h = hashlib.blake2b(digest_size=16)
    for obj in objs:
        _feed(h, obj)
    return h.hexdigest()


def _feed(h, obj, depth: int = 0) -> None:
    if depth > 12:
        raise ValueError("content_digest: nested too deep")
    if isinstance(obj, np.ndarray):
        a = np.ascontiguousarray(obj)
        h.update(f"nd{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes() if a.dtype != object else repr(a.tolist()).encode())
    elif hasattr(obj, "tocsr") and hasattr(obj, "nnz"):  # scipy.sparse
        m = obj.tocsr()
        h.update(f"sp{m.shape}".encode())
        for a in (m.data, m.indices, m.indptr):
            _feed(h, a, depth + 1)
    elif type(obj).__module__.startswith("torch") and hasattr(obj, "detach"):
        _feed(h, obj.detach().cpu().numpy(), depth + 1)
    elif dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        h.update(f"dc{type(obj).__qualname__}".encode())
        for f in dataclasses.fields(obj):
            h.update(f.name.encode())
            _feed(h, getattr(obj, f.name), depth + 1)
    elif isinstance(obj, dict):
        h.update(f"dict{len(obj)}".encode())
        for k in sorted(obj, key=repr):
            _feed(h, k, depth + 1)
            _feed(h, obj[k], depth + 1)
    elif isinstance(obj, (list, tuple)):
        h.update(f"seq{len(obj)}".encode())
        for v in obj:
            _feed(h, v, depth + 1)
    elif isinstance(obj, float):
        h.update(f"f{obj!r}".encode())
    else:
        h.update(f"{type(obj).__qualname__}:{obj!r}".encode())


class EquilibriumStore:
    """Equilibria (:class:`~kgarment.sim.StateResult`, or the evaluator's ``Equilibrium``)
    in ``folder``, one ``.npz`` per key (a tuple of strings; see the module docstring)."""

    def __init__(self, folder):
        self.folder = Path(folder)
        self.hits = self.misses = 0

    def _file(self, key: tuple) -> Path:
        return self.folder / f"{content_digest(SIM_MODEL, code_digest(), *key)}.npz"

    def get(self, key: tuple):
        """The entry of ``key``, or None (not there, or unreadable: reported)."""
        path = self._file(key)
        if not path.is_file():
            self.misses += 1
            return None
        try:
            with np.load(path, allow_pickle=False) as z:
                value = _read(z)
        except Exception as exc:  # noqa: BLE001 - a damaged entry is solved again, never fatal
            log.warning("equilibrium store: %s unreadable (%s); solving that state again", path, exc)
            self.misses += 1
            return None
        self.hits += 1
        return value

    def put(self, key: tuple, value) -> None:
        """Keep ``value`` under ``key`` (a failure to write is reported, not raised: the
        store only saves time)."""
        path = self._file(key)
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            buf = io.BytesIO()
            np.savez_compressed(buf, **_fields(value))
            tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
            tmp.write_bytes(buf.getvalue())
            os.replace(tmp, path)
        except OSError as exc:
            log.warning("equilibrium store: could not write %s (%s)", path, exc)


def _result_fields(r: StateResult, prefix: str) -> dict:
    conv = dataclasses.asdict(r.convergence)
    conv["history"] = list(conv["history"])
    sizes = np.array([len(c) for c in r.clutch_energy], dtype=np.int64)
    cat = (lambda parts: np.concatenate(parts) if parts else np.zeros(0))
    return {f"{prefix}x": r.x, f"{prefix}garment_energy": r.garment_energy,
            f"{prefix}garment_density": r.garment_density, f"{prefix}clutch_sizes": sizes,
            f"{prefix}clutch_energy": cat(list(r.clutch_energy)), f"{prefix}clutch_density": cat(list(r.clutch_density)),
            f"{prefix}n_garment": np.array(len(r.garment_x) if r.garment_x is not None else -1),
            f"{prefix}meta": np.array(json.dumps({"name": r.name, "energy": r.energy, "convergence": conv,
                                                  "friction": r.friction}))}


def _fields(value) -> dict:
    if isinstance(value, StateResult):
        return {"kind": np.array("result"), **_result_fields(value, "")}
    out = {"kind": np.array("equilibrium"), "from_path": np.array(bool(value.from_path)),
           **_result_fields(value.result, "")}
    if value.other is not None:
        out.update(_result_fields(value.other, "other_"))
    return out


def _result(z, prefix: str) -> StateResult:
    meta = json.loads(str(z[f"{prefix}meta"]))
    conv = meta["convergence"]
    conv["history"] = tuple(conv["history"])
    sizes = z[f"{prefix}clutch_sizes"]
    cuts = np.cumsum(sizes)[:-1]
    x = z[f"{prefix}x"]
    n = int(z[f"{prefix}n_garment"])
    return StateResult(name=meta["name"], x=x, garment_energy=z[f"{prefix}garment_energy"],
                       garment_density=z[f"{prefix}garment_density"],
                       clutch_energy=list(np.split(z[f"{prefix}clutch_energy"], cuts)) if len(sizes) else [],
                       clutch_density=list(np.split(z[f"{prefix}clutch_density"], cuts)) if len(sizes) else [],
                       energy={k: float(v) for k, v in meta["energy"].items()}, convergence=Convergence(**conv),
                       garment_x=None if n < 0 else x[:n], friction=float(meta["friction"]))


def _read(z):
    if str(z["kind"]) == "result":
        return _result(z, "")
    from kgarment.design.evaluate import Equilibrium

    other = _result(z, "other_") if "other_x" in z.files else None
    return Equilibrium(_result(z, ""), other, bool(z["from_path"]))
