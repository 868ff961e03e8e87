"""What the studio's controllers need from the page they work for.

The controllers (:mod:`.edit`, :mod:`.simulations`, :mod:`.optimise`) hold a :class:`Page`
(the :class:`kgarment.studio.app.Studio` in the running app) and reach the edited state,
the settings and the page's messages and refreshes only through it, so none of them
imports the app or the viser panel.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Protocol

from kgarment.studio.folders import Folders
from kgarment.studio.settings import Settings
from kgarment.studio.state import StudioState


class Page(Protocol):
    """The page as its controllers see it.

    state : the edited layers (replaced when another source is opened);  settings : the
    page's settings;  lock : held while the page reads or swaps what it shows;  device :
    torch device for simulations and optimisations;  folders : where the page may read
    (every path typed into it is checked there first).
    """

    state: StudioState
    settings: Settings
    lock: threading.RLock
    device: str
    folders: Folders

    def say(self, text: str, error: bool = False, notify: bool = False) -> None:
        """Show ``text`` in the status line (errors and ``notify`` also pop up)."""

    def refresh(self, *, scene: bool = False, body: bool = False, results: bool = False, run: bool = False,
                settings: bool = False, clutch: bool = False) -> None:
        """Bring parts of the page up to date: the 3D scene (``body`` too: the body mesh),
        the results table, the run panel, the controls that mirror the settings, the
        selected clutch's controls."""

    def confirm_write(self, path: Path) -> bool:
        """Whether ``path`` may be written: new, or asked for twice in a row (the first time
        the page warns that it exists)."""

    def show_progress(self, job: str, text: str) -> None:
        """Progress text of a background job ("simulation" or "optimisation")."""

    def clutch_defaults(self) -> dict[str, float | bool]:
        """Length (m), width (m), prestrain and clip for a new clutch (the panel's values)."""
