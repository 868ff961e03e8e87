"""Files: kgarment's cache folder and the one atomic writer every module uses.

``KGARMENT_CACHE_DIR`` moves kgarment's own cache (posed body meshes); it defaults to
``~/.cache/kgarment``. Anny keeps its own model cache in ``ANNY_CACHE_DIR``
(default ``~/.cache/anny``).

Every file kgarment writes goes through :func:`atomic_write_bytes` (write a temporary file
in the same folder, then rename it over the target), so a killed process never leaves a
half-written checkpoint, metrics table or mesh behind.
"""

from __future__ import annotations

import io
import json
import math
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from kgarment.errors import KgarmentError


def cache_dir() -> Path:
    """The kgarment cache folder (created if missing)."""
    root = Path(os.environ.get("KGARMENT_CACHE_DIR", Path.home() / ".cache" / "kgarment"))
    root.mkdir(parents=True, exist_ok=True)
    return root


_UMASK = os.umask(0o022)  # read once at import (os.umask can only be read by setting it)
os.umask(_UMASK)


def atomic_write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (parent folders are created), with the
    permissions a plain ``open(path, "w")`` would give it (the temporary file's are 0600)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.chmod(tmp, 0o666 & ~_UMASK)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def atomic_write_text(path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    return atomic_write_bytes(path, text.encode())


def finite_json(obj):
    """``obj`` (nested dicts, lists, tuples, numbers, strings) with every float that is not
    finite (NaN, +-inf: an undefined share, a missing value) replaced by None."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: finite_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [finite_json(v) for v in obj]
    return obj


def json_text(obj, indent: int | None = 1) -> str:
    """Strict JSON (RFC 8259) of ``obj`` for the files users and other programs read: values
    that are not finite written as null (Python's ``json`` would write NaN, which JSON.parse,
    jq and most readers refuse)."""
    return json.dumps(finite_json(obj), indent=indent, allow_nan=False)


def seconds_left(spent_s: float, done: float, total: float) -> float | None:
    """Seconds the ``total - done`` remaining steps take at the mean time per step of the
    ``done`` that took ``spent_s`` seconds (a linear estimate); None before the first."""
    if done <= 0:
        return None
    return max(total - done, 0.0) * spent_s / done


def time_left(spent_s: float, done: int, total: int) -> str:
    """'S s so far, about R s to go' after ``done`` of ``total`` equal steps took
    ``spent_s`` seconds (:func:`seconds_left`); '' before the first is done."""
    left = seconds_left(spent_s, done, total)
    return "" if left is None else f"{spent_s:.0f} s so far, about {left:.0f} s to go"


def atomic_save_npz(path, *, compressed: bool = True, **arrays) -> Path:
    """Write an ``.npz`` of ``arrays`` atomically, compressed unless ``compressed=False``
    (a file rewritten often: deflate took 80 ms of a design run's 1.5 MB checkpoint, the
    uncompressed write 7 ms)."""
    buf = io.BytesIO()
    (np.savez_compressed if compressed else np.savez)(buf, **arrays)
    return atomic_write_bytes(path, buf.getvalue())


def write_ply(path, vertices: np.ndarray, faces: np.ndarray, face_values: dict[str, np.ndarray] | None = None) -> Path:
    """A binary PLY with per-face scalar properties (e.g. energy density, J/m^2), atomically.

    vertices : (n, 3) m; faces : (m, 3) int; face_values : name -> (m,) float arrays.
    """
    import trimesh

    mesh = trimesh.Trimesh(np.asarray(vertices), np.asarray(faces), process=False)
    for k, v in (face_values or {}).items():
        mesh.face_attributes[k] = np.asarray(v, dtype=np.float64)
    return atomic_write_bytes(path, trimesh.exchange.ply.export_ply(mesh, include_attributes=True))


MARKER = ".kgarment"  # in every folder kgarment creates: what wrote it (JSON)
RUN_FILES = ("problem.toml", "problem.txt")  # a run folder written before the marker existed


def save_figure(fig, path, title: str = "") -> Path:
    """Write the matplotlib figure ``fig`` to ``path`` (its folder made; the format from the
    suffix), with ``title`` above it where given, laid out tight, and close it."""
    import matplotlib.pyplot as plt

    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path


def mark_folder(path, kind: str) -> Path:
    """Mark ``path`` as a folder kgarment created (``kind``: run, fabrication, ...)."""
    from kgarment import __version__

    return atomic_write_text(Path(path) / MARKER, json.dumps({"kind": kind, "kgarment": __version__}) + "\n")


def owned(path) -> bool:
    """Whether ``path`` is a folder kgarment created (its marker, or a run folder's inputs)."""
    path = Path(path)
    return path.is_dir() and ((path / MARKER).is_file() or all((path / f).is_file() for f in RUN_FILES))


def folder_kind(path) -> str | None:
    """What kind of kgarment folder ``path`` is (its marker's ``kind``: run, fabrication,
    sweep, ...; "run" for a run folder written before the marker existed), None if none."""
    path = Path(path)
    try:
        return str(json.loads((path / MARKER).read_text()).get("kind"))
    except (OSError, ValueError, AttributeError):
        return "run" if all((path / f).is_file() for f in RUN_FILES) else None


def _empty(path: Path) -> bool:
    return path.is_dir() and not any(path.iterdir())


def check_replaceable(path, force: bool, hint: str = "use --force to replace it", kind: str = "run") -> Path:
    """Check, before any work, that the output folder ``path`` can be written: missing, empty,
    or (with ``force``) a folder kgarment created of the same ``kind``.  Anything else ->
    KgarmentError, nothing touched: a file, a folder of other files (kgarment never deletes
    what it did not create), a kgarment folder of another kind (a design run is never
    replaced by cut files, nor the other way round), a parent that is not a writable folder.
    ``hint``: what to do about an existing one."""
    path = check_output_folder(path, "output folder")
    if path.is_dir() and not _empty(path):
        if not owned(path):
            raise KgarmentError(f"{path} exists and holds files kgarment did not write; it is never replaced, "
                                "give another output folder")
        if (other := folder_kind(path)) != kind:
            raise KgarmentError(f"{path} is a kgarment {other} folder, not a {kind} folder; it is never replaced "
                                "by one, give another output folder")
        if not force:
            raise KgarmentError(f"output folder {path} exists; {hint}")
    return path


def replace_folder(path, fill, kind: str) -> Path:
    """Write a new folder ``path`` with ``fill(tmp)`` and only then put it in place: the new
    folder is filled beside the old one, the old one (checked by :func:`check_replaceable`)
    is swapped out and deleted last, so a failure while filling leaves the old one as it was.
    Returns ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=path.parent, prefix=f".{path.name}.new-"))
    try:
        mark_folder(tmp, kind)
        fill(tmp)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    old = None
    if path.exists():
        if not (_empty(path) or (owned(path) and folder_kind(path) == kind)):  # checked before the work; again now
            shutil.rmtree(tmp, ignore_errors=True)
            raise KgarmentError(f"{path} holds files kgarment did not write or is another kind of kgarment "
                                "folder; it is never replaced")
        old = Path(tempfile.mkdtemp(dir=path.parent, prefix=f".{path.name}.old-"))
        os.replace(path, old / path.name)
    os.replace(tmp, path)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    return path


def check_output_folder(path, flag: str = "--out") -> Path:
    """Check, before any work, that a folder ``path`` (named by ``flag``) can be created or
    written into: not a file, its nearest existing parent a writable folder."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise KgarmentError(f"{flag} {path} is a file, not a folder")
    _check_parent(path, [path, *path.parents], flag)
    return path


def check_kind(path, kind: str, flag: str = "--out", legacy: tuple[str, ...] | None = None) -> Path:
    """An output folder that commands of one ``kind`` add files to (simulate's results, a
    reproduction's experiments): never a kgarment folder of another kind (a design run, cut
    files); with ``legacy`` (the files such a folder held before markers existed), a
    non-empty folder without a marker must hold one of them, else it is not kgarment's."""
    path = check_output_folder(path, flag)
    if path.is_dir() and not _empty(path):
        other = folder_kind(path)
        if other is not None and other != kind:
            raise KgarmentError(f"{flag} {path} is a kgarment {other} folder, not a {kind} folder; give another "
                                "output folder")
        if other is None and legacy is not None and not any((path / f).exists() for f in legacy):
            raise KgarmentError(f"{flag} {path} exists and holds files kgarment did not write; give another "
                                "output folder")
    return path


def check_output_file(path, flag: str, force: bool = False, suffixes: tuple[str, ...] = ()) -> Path:
    """Check, before any work, that a file ``path`` (named by ``flag``, e.g. --json) can be
    written: not a folder, one of ``suffixes`` (e.g. (".png", ".pdf") when given), its nearest
    existing parent a writable folder, and not an existing file unless ``force`` -- never an
    existing file of a folder kgarment made (a run's ``problem.toml`` or ``metrics.json``)."""
    path = Path(path)
    if path.is_dir():
        raise KgarmentError(f"{flag} {path} is a folder; give a file name")
    if suffixes and path.suffix.lower() not in suffixes:
        raise KgarmentError(f"{flag} {path}: give a {' or '.join(suffixes)} file")
    if path.exists():
        home = next((q for q in path.resolve().parents if owned(q)), None)
        if home is not None:
            raise KgarmentError(f"{flag} {path} is a file of the kgarment {folder_kind(home)} folder {home}; "
                                "it is never overwritten, give another file")
        if not force:
            raise KgarmentError(f"{flag} {path} exists; use --force to overwrite it")
    _check_parent(path, path.parents, flag)
    return path


def _check_parent(path: Path, candidates, flag: str) -> None:
    """The first existing one of ``candidates`` (``path``'s folder and its parents) must be a
    writable folder."""
    parent = next((q for q in candidates if q.exists()), Path("."))
    if not parent.is_dir():
        raise KgarmentError(f"{flag} {path}: {parent} is a file, not a folder")
    if not os.access(parent, os.W_OK):
        raise KgarmentError(f"{flag} {path}: cannot write into {parent} (permission denied)")
    try:  # what access() cannot tell (root, a read-only or special file system): a file made and removed
        fd, probe = tempfile.mkstemp(dir=parent, prefix=".kgarment-probe-")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise KgarmentError(f"{flag} {path}: cannot write into {parent} ({exc.strerror or exc})") from None


def read_toml(path, what: str) -> tuple[str, dict]:
    """The text and the parsed tables of the TOML file ``path`` (a ``what``, e.g. "problem
    file"); not UTF-8 or not valid TOML -> one KgarmentError naming the file."""
    import tomllib

    try:
        text = Path(path).read_text(encoding="utf-8")
        return text, tomllib.loads(text)
    except UnicodeDecodeError:
        raise KgarmentError(f"{what} {path} is not UTF-8 text (TOML is)") from None
    except tomllib.TOMLDecodeError as exc:
        raise KgarmentError(f"{what} {path} is not valid TOML: {exc}") from None


def make_folder(path, kind: str) -> Path:
    """Create the output folder ``path`` (checked by :func:`check_kind`) and mark it as a
    ``kind`` folder when kgarment makes it (missing or empty); one the user had filled, or an
    older kgarment folder without a marker, is left unmarked."""
    path = Path(path)
    fresh = not path.exists() or _empty(path)
    path.mkdir(parents=True, exist_ok=True)
    if fresh:
        mark_folder(path, kind)
    return path


def read_json_object(path, what: str, keys=()) -> dict:
    """The JSON object in ``path`` (a kgarment ``what``, e.g. "final evaluation") holding
    ``keys``; missing, unreadable, not JSON, not an object or lacking a key -> one
    KgarmentError naming the file."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise KgarmentError(f"{what} {path} not found") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise KgarmentError(f"{what} {path} is damaged ({type(exc).__name__})") from None
    if not isinstance(doc, dict):
        raise KgarmentError(f"{what} {path} is damaged (not a JSON object)")
    missing = [k for k in keys if k not in doc]
    if missing:
        raise KgarmentError(f"{what} {path} is damaged (no {missing[0]!r})")
    return doc


def load_npz(path, what: str, keys=()) -> dict:
    """The arrays of ``path`` (a kgarment ``what``) as a dict; a missing, damaged or foreign
    file -> one KgarmentError naming it (and the ``keys`` it must hold)."""
    import zipfile

    path = Path(path)
    if not path.is_file():
        raise KgarmentError(f"{what} not found: {path}")
    try:
        with np.load(path, allow_pickle=False) as z:
            missing = [k for k in keys if k not in z.files]
            if missing:
                raise KgarmentError(f"{path} is not a kgarment {what}: it has no {missing[0]!r} array")
            return {k: z[k] for k in z.files}
    except KgarmentError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as exc:
        raise KgarmentError(f"{path} is damaged or not a kgarment {what} ({type(exc).__name__}: {exc})") from None
