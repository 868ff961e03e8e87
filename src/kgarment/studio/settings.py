"""The page's settings (saved with a session) and the editing tools.

Plain data shared by the page (:mod:`kgarment.studio.app`), its controls
(:mod:`kgarment.studio.panel`) and the edit controller (:mod:`kgarment.studio.edit`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

TOOLS = ("select", "place clutch", "move clutch", "aim clutch", "paint reinforcement", "erase reinforcement",
         "paint attachments", "erase attachments")
BRUSH_TOOLS = {"paint reinforcement": ("design", True), "erase reinforcement": ("design", False),
               "paint attachments": ("attached", True), "erase attachments": ("attached", False)}
"""Brush tool -> (layer of :class:`~kgarment.studio.state.StudioState`, value painted)."""


@dataclass
class Settings:
    """What the page shows and how it edits (saved with a session).

    motion : "rest" or a posed motion;  clutches_on : show (and draw) the clutch-ON
    equilibrium;  pose : blend rest -> target in [0, 1];  mode : colour mode
    (:data:`kgarment.studio.view.MODES`);  show_body : draw the body;  tool : one of
    :data:`TOOLS`;  radius : brush radius, m;  brush_mode : "surface" | "euclidean";
    sim_motions : motions ticked for simulation.
    """

    motion: str = "rest"
    clutches_on: bool = True
    pose: float = 1.0
    mode: str = "design"
    show_body: bool = True
    tool: str = "select"
    radius: float = 0.02
    brush_mode: str = "surface"
    sim_motions: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> Settings:
        """Settings from a saved dict; unknown keys and values of the wrong type are ignored."""
        s = cls()
        for k, v in d.items():
            if hasattr(s, k) and isinstance(v, type(getattr(s, k))):
                setattr(s, k, v)
        return s

    def fit(self, posed: Sequence[str], motions: Sequence[str]) -> None:
        """Keep the shown motion only if it is one of ``posed`` (else "rest"), and the
        simulated motions only among the problem's ``motions`` (all of them if none is left)."""
        if self.motion != "rest" and self.motion not in posed:
            self.motion = "rest"
        self.sim_motions = [m for m in self.sim_motions if m in motions] or list(motions)
