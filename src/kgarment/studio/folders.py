"""Where the page may read: the folders given on the command line, and nowhere else.

Every path typed into the page (Open, Run folder, Design B from) must resolve, symbolic links
and ``..`` followed, under one of the studio's folders: ``--runs`` (where it writes), the
problem's folder (the folder of the problem file, run or session the studio was started
on), ``--session``, and the run that session shows.  The check looks at the path only: a
path outside is refused with one line before anything under it is opened, listed or read.
What the page writes is a plain name under ``--runs`` (:func:`kgarment.studio.session.studio_path`).
"""

from __future__ import annotations

from pathlib import Path

from kgarment.errors import KgarmentError


class Folders:
    """The folders the page reads from (``roots``, resolved, in the order given)."""

    def __init__(self, *roots):
        self.roots = tuple(dict.fromkeys(Path(r).resolve() for r in roots if r is not None))

    @classmethod
    def of(cls, opened, runs, session=None) -> Folders:
        """The folders of a studio started on ``opened`` (a
        :class:`~kgarment.studio.session.Opened`) with ``--runs`` and ``--session``."""
        source = opened.problem.source
        return cls(runs, source.parent if source is not None else None, session, opened.run)

    def describe(self) -> str:
        return ", ".join(str(r) for r in self.roots)

    def inside(self, text: str, what: str) -> Path:
        """``text`` as a Path when it lies under one of the folders (else a one-line error);
        for 'RUN@K' both the whole text and RUN must."""
        text = str(text).strip()
        candidates = [text] + ([text.rpartition("@")[0]] if "@" in text else [])
        for c in candidates:
            p = Path(c).resolve()
            if not any(p == r or p.is_relative_to(r) for r in self.roots):
                raise KgarmentError(f"{what} {text}: the studio reads only under its folders ({self.describe()}: "
                                    "--runs, the problem's folder, --session)")
        return Path(text)
