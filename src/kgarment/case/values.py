"""The design variable as the simulator reads it: x_e in {x_min, 1} per garment face."""

from __future__ import annotations

import numpy as np

from kgarment.constants import X_MIN


def design_values(reinforced: np.ndarray) -> np.ndarray:
    """(m,) float64 design for the simulator from (m,) bool ``reinforced``: 1.0 where
    reinforced, :data:`~kgarment.constants.X_MIN` (plain cloth) elsewhere."""
    return np.where(np.asarray(reinforced, dtype=bool), 1.0, X_MIN)
