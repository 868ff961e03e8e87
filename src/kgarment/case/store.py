"""Equilibria kept on disk: a run folder's ``equilibria/``, read back by later evaluations.

A design run ends with the evaluation of its final design (the one design evaluator,
:mod:`kgarment.evaluate.evaluator`): every state from two starts, the fully reinforced
garment's states, one state per clutch and motion for the loads.  ``kgarment evaluate RUN``
(with or without ``--path``) and ``kgarment plan RUN`` then need the same equilibria again,
in another process.  The evaluator's solves go through the run's store
(:meth:`kgarment.case.Case.solve`): a solve done before -- the same state
from the same start -- is read back instead of solved again, so a later command gives
the same numbers to the last digit without the work, whatever it builds from them (the
two starts, the fully reinforced references, the load states, the frames of the force over
the motion and their repairs).

An entry is one solve, keyed by everything its result depends on: the simulation model's
version (``SIM_MODEL``), a digest of the simulator's source files (:data:`CODE`: an entry
written by code that solves differently is not used), the solver options (not the number of worker
processes: solves repeat bit for bit in any process), the state's simulation model
(garment, clutches, materials, clutch model: every array of it), the design's values, the
posed body (vertices and normals), the skin-tight garment, its attachments and the clutch
activation (:func:`state_digest`) and the start (the skin-tight garment, or
the start's positions).  A different clutch model or friction given on the command line,
another body, design or start simply finds no entry.  One ``.npz`` file per entry (no
pickle: nothing in a run folder is executed on reading), written to a temporary name and
renamed, so a reader never sees half a file; an unreadable entry is reported and solved
again.  Size: about 0.1 MB per solve at subdivision 0 (the main job's final evaluation:
~40 solves, 3 MB), ~1.3 MB at subdivision 2.

The fully reinforced garment's solves (iteration 0 of every design run, the references of
rho in every evaluation) depend on the problem, not on a design: :func:`shared_store`
keeps them for every run on the machine, in kgarment's cache (``KGARMENT_CACHE_DIR``,
``equilibria/``), as Anny keeps its model: the first run of a garment, its motions and
clutches solves them, later runs, evaluations and reproductions of the same read them
back (the same bits: the key names every input).  Only converged solves are kept there.
One folder per code version (:func:`code_digest`); the :data:`SHARED_VERSIONS` most
recently used stay, older ones are removed.  ``KGARMENT_SOLVE_CACHE=0`` turns it off,
``KGARMENT_SOLVE_CACHE=FOLDER`` puts it in FOLDER (the test suite: one per session).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import logging
import os
import re
import shutil
import weakref
from pathlib import Path

import numpy as np

from kgarment.constants import SIM_MODEL
from kgarment.io import atomic_save_npz, cache_dir
from kgarment.sim import SimState, StateResult
from kgarment.sim.options import Convergence

log = logging.getLogger(__name__)
FOLDER = "equilibria"  # the store's folder in a run folder
# the sources whose change can change what a solve returns (a key names all its inputs, so
# the evaluation's own logic -- which solves it asks for -- is not among them)
CODE = ("sim", "case/setup.py", "case/store.py", "constants.py")
SHARED = "equilibria"  # the shared store's folder in kgarment's cache (shared_store)
SHARED_VERSIONS = 4  # code versions whose folders the shared store keeps (the most recently used)
DIGESTS_KEPT = 64  # remembered digests beyond which those of objects that are gone are forgotten
_VERSION = re.compile(r"[0-9a-f]{32}")  # a code version's folder name (content_digest)


@functools.cache
def code_digest() -> str:
    """A digest of the source files that make a solve (:data:`CODE`)."""
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


def design_digest(design: np.ndarray) -> str:
    """A digest of a design's values (m,), exactly (float64 bytes)."""
    return hashlib.blake2b(np.ascontiguousarray(design, dtype=np.float64).tobytes(), digest_size=12).hexdigest()


def state_digest(state: SimState) -> str:
    """A digest of what a state's equilibrium depends on besides the design: the posed
    body, the skin-tight garment, its attachments, the clutch activation and the friction
    anchor where the state has one (not the name)."""
    m = state.motion
    h = hashlib.blake2b(m.body.key.encode(), digest_size=12)
    for a in (m.garment_x0, m.attach_faces, m.attach_targets, np.asarray(state.activation, dtype=np.float64)):
        h.update(np.ascontiguousarray(a).tobytes())
    if state.anchor is not None:  # skin friction held elsewhere than at the skin-tight garment
        h.update(b"anchor" + np.ascontiguousarray(state.anchor, dtype=np.float64).tobytes())
    return h.hexdigest()


def shared_store() -> EquilibriumStore | None:
    """The store of fully reinforced garments' solves shared by every run on this machine
    (module docstring), or None where ``KGARMENT_SOLVE_CACHE=0`` or its folder cannot be
    made (reported once).  Its folder is ``cache_dir()/equilibria/<code version>``
    (``KGARMENT_SOLVE_CACHE=FOLDER``: in FOLDER); opening it marks the version used and
    removes the folders of all but the :data:`SHARED_VERSIONS` most recently used versions
    (only folders named like a version: nothing else there is touched)."""
    setting = os.environ.get("KGARMENT_SOLVE_CACHE", "").strip()
    if setting.lower() in ("0", "off", "no", "false"):
        return None
    try:
        root = cache_dir() / SHARED if setting.lower() in ("", "1", "on", "yes", "true") else Path(setting)
    except OSError as exc:
        log.warning("equilibrium cache: kgarment's cache folder is not usable (%s); solving without it", exc)
        return None
    folder = root / content_digest(SIM_MODEL, code_digest())
    if folder in _SHARED:
        return _SHARED[folder]
    store = None
    try:
        folder.mkdir(parents=True, exist_ok=True)
        os.utime(folder)  # used now: the pruning below keeps the most recently used
        versions = sorted((p for p in root.iterdir() if p.is_dir() and _VERSION.fullmatch(p.name)),
                          key=lambda p: p.stat().st_mtime, reverse=True)
        for old in versions[SHARED_VERSIONS:]:
            if old != folder:
                shutil.rmtree(old, ignore_errors=True)
    except OSError as exc:  # the store only saves time
        log.warning("equilibrium cache: %s not usable (%s); solving without it", folder, exc)
    else:
        store = EquilibriumStore(folder, converged_only=True)
    _SHARED[folder] = store  # an unusable folder is reported once per process
    return store


_SHARED: dict[Path, EquilibriumStore | None] = {}  # shared_store's instance per folder (this process)


def run_store(run) -> EquilibriumStore:
    """The store of run folder ``run`` (its :data:`FOLDER`)."""
    return EquilibriumStore(Path(run) / FOLDER)


class EquilibriumStore:
    """Solved states (:class:`~kgarment.sim.StateResult`) in ``folder``, one ``.npz`` per
    key (see the module docstring).  ``hits`` / ``misses`` count the solves read back /
    not found; ``borrowed``: of the misses, those read from the ``also`` store of
    :meth:`solve` (the shared one) instead of solved.  ``converged_only``: solves that did
    not converge are not kept (solved again, and reported again, next time)."""

    def __init__(self, folder, converged_only: bool = False):
        self.folder = Path(folder)
        self.converged_only = converged_only
        self.hits = self.misses = self.borrowed = 0
        self.unwritable = False  # a write failed: reported once, no more tried
        self._digests: dict[int, tuple[weakref.ref, str]] = {}  # id -> (a reference to the object, its digest)

    def solve(self, case, design: np.ndarray, states: list, warm_start, options,
              also: EquilibriumStore | None = None) -> list[StateResult]:
        """``case.solve_now`` of the states not in the store, the others read back (under
        the states' own names); the new ones are kept.  ``also``: a second store (the
        shared one) looked in for what this one lacks; what it has is copied here, what is
        solved is kept in both."""
        warm = list(warm_start) if warm_start is not None else [None] * len(states)
        opts = content_digest(dataclasses.replace(options, workers=0))
        d = design_digest(design)
        keys = [(opts, self._digest(case.model_of(s.motion.name)), d, state_digest(s),
                 self._digest(s.motion.body.normals),  # the body's key covers its vertices only
                 "skin-tight" if w is None else content_digest(np.asarray(w, dtype=np.float64)))
                for s, w in zip(states, warm)]
        out: list = [None] * len(states)
        for i, key in enumerate(keys):
            got = self.get(key)
            if got is None and also is not None:
                got = also.get(key)
                if got is not None:
                    self.borrowed += 1
                    self.put(key, got)
            if got is not None:
                out[i] = dataclasses.replace(got, name=states[i].name)
        todo = [i for i, r in enumerate(out) if r is None]
        if todo:
            solved = case.solve_now(design, [states[i] for i in todo], [warm[i] for i in todo], options)
            for i, r in zip(todo, solved):
                out[i] = r
                self.put(keys[i], r)
                if also is not None:
                    also.put(keys[i], r)
        return out

    def _digest(self, obj) -> str:
        """content_digest of a large object that stays the same (a model, a body's normals),
        computed once per object."""
        hit = self._digests.get(id(obj))
        if hit is not None and hit[0]() is obj:
            return hit[1]
        digest = content_digest(obj)
        try:
            ref = weakref.ref(obj)  # not kept alive by the store (the shared one lives as long as the process)
        except TypeError:
            return digest
        self._digests[id(obj)] = (ref, digest)
        if len(self._digests) > DIGESTS_KEPT:  # forget the objects that are gone
            self._digests = {k: v for k, v in self._digests.items() if v[0]() is not None}
        return digest

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

    def put(self, key: tuple, value: StateResult) -> None:
        """Keep ``value`` under ``key`` (a failure to write is reported, not raised: the
        store only saves time)."""
        if self.unwritable or (self.converged_only and not value.converged):
            return
        path = self._file(key)
        try:
            atomic_save_npz(path, **_fields(value))
        except OSError as exc:
            self.unwritable = True
            log.warning("equilibrium store: could not write %s (%s); solving on without keeping solves there",
                        path, exc)


def _fields(r: StateResult) -> dict:
    """A solve's result as the arrays of its ``.npz`` (the record and the energies as JSON)."""
    conv = dataclasses.asdict(r.convergence)
    conv["history"] = list(conv["history"])
    sizes = np.array([len(c) for c in r.clutch_energy], dtype=np.int64)
    cat = (lambda parts: np.concatenate(parts) if parts else np.zeros(0))
    return {"x": r.x, "garment_energy": r.garment_energy, "garment_density": r.garment_density,
            "clutch_sizes": sizes, "clutch_energy": cat(list(r.clutch_energy)),
            "clutch_density": cat(list(r.clutch_density)),
            "n_garment": np.array(len(r.garment_x) if r.garment_x is not None else -1),
            "meta": np.array(json.dumps({"name": r.name, "energy": r.energy, "convergence": conv,
                                         "friction": r.friction}, default=_plain))}


def _plain(obj):
    """numpy scalars (a bool_ or an integer in a record) as Python ones for JSON."""
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f"{type(obj).__name__} is not JSON serialisable")


def _read(z) -> StateResult:
    """The StateResult of an entry's arrays (:func:`_fields`)."""
    meta = json.loads(str(z["meta"]))
    conv = meta["convergence"]
    conv["history"] = tuple(conv["history"])
    sizes = z["clutch_sizes"]
    cuts = np.cumsum(sizes)[:-1]
    x = z["x"]
    n = int(z["n_garment"])
    return StateResult(name=meta["name"], x=x, garment_energy=z["garment_energy"],
                       garment_density=z["garment_density"],
                       clutch_energy=list(np.split(z["clutch_energy"], cuts)) if len(sizes) else [],
                       clutch_density=list(np.split(z["clutch_density"], cuts)) if len(sizes) else [],
                       energy={k: float(v) for k, v in meta["energy"].items()}, convergence=Convergence(**conv),
                       garment_x=None if n < 0 else x[:n], friction=float(meta["friction"]))
