"""Material presets and the design / activation interpolations (SI units).

Two presets (the method page (docs/method/index.md, "Energies")):

========================  ======================  ===========================
material                  ``paper`` (default)     ``reference``
========================  ======================  ===========================
cloth (d = 0)             0.5 MPa, 0.27 mm        0.5 MPa, 0.27 mm
reinforced cloth (d = 1)  0.5 GPa, 0.35 mm        5.7 MPa, 0.35 mm
clutch ON (g = 1)         3.0 GPa, 0.35 mm        25.7 MPa, 0.35 mm
clutch OFF (g = 0)        = cloth                 0.5 MPa, 0.27 mm
========================  ======================  ===========================

The paper gives moduli but no thicknesses; the ``paper`` preset borrows the reference
implementation's thicknesses (0.27 mm cloth, 0.35 mm reinforced and clutch).
Poisson's ratio is 0.33 for every material.

Design interpolation (soft-kill BESO, ``p = 1.6``, ``x_min = 0.001``), per garment face::

    Y(d) = d^p Y1 + (1 - d^p) Y0
    t(d) = d^p t1 + (1 - d^p) t0        # our choice: thickness follows the same rule

so ``d = 1`` is exactly the reinforced material and ``d = x_min`` is cloth up to
``x_min^p = 1.6e-5`` of the difference.  The membrane energy is proportional to ``Y t``,
so the explicit design derivative of an element's energy at fixed positions is
``E_e * dlog(Y t)/dd`` (see :func:`log_stiffness_derivative`).

Clutch activation ``g`` in [0, 1] (continuous, per clutch)::

    Y(g) = g Y_on + (1 - g) Y_off,   t(g) = g t_on + (1 - g) t_off.

Membranes use plane-stress Lame parameters (thin sheet, no stress through the
thickness)::

    mu = Y / (2 (1 + nu)),   lambda = Y nu / (1 - nu^2)

With these the small-strain limit of the 2D neo-Hookean energy is exactly plane-stress
linear elasticity of modulus ``Y`` and Poisson ratio ``nu`` (the 3D value
``lambda = Y nu / ((1 + nu)(1 - 2 nu))`` would make the sheet too stiff in area change).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kgarment.constants import PENALTY, X_MIN


@dataclass(frozen=True)
class MaterialPreset:
    """Young's moduli (Pa) and thicknesses (m) of the four materials."""

    name: str
    young_cloth: float
    thick_cloth: float
    young_reinforced: float
    thick_reinforced: float
    young_clutch_on: float
    thick_clutch_on: float
    young_clutch_off: float
    thick_clutch_off: float
    poisson: float = 0.33
    penal: float = PENALTY
    x_min: float = X_MIN

    @property
    def cloth_stiffness(self) -> float:
        """Membrane stiffness ``Y t`` of plain cloth, N/m (the simulator's reference)."""
        return self.young_cloth * self.thick_cloth


PAPER = MaterialPreset(
    name="paper",
    young_cloth=0.5e6, thick_cloth=0.27e-3,
    young_reinforced=0.5e9, thick_reinforced=0.35e-3,
    young_clutch_on=3.0e9, thick_clutch_on=0.35e-3,
    young_clutch_off=0.5e6, thick_clutch_off=0.27e-3,
)

REFERENCE = MaterialPreset(
    name="reference",
    young_cloth=0.5e6, thick_cloth=0.27e-3,
    young_reinforced=5.7e6, thick_reinforced=0.35e-3,
    young_clutch_on=25.7e6, thick_clutch_on=0.35e-3,
    young_clutch_off=0.5e6, thick_clutch_off=0.27e-3,
)

PRESETS: dict[str, MaterialPreset] = {"paper": PAPER, "reference": REFERENCE}


def get_preset(preset: str | MaterialPreset = "paper") -> MaterialPreset:
    """Return a preset by name (``"paper"`` or ``"reference"``) or pass one through."""
    if isinstance(preset, MaterialPreset):
        return preset
    try:
        return PRESETS[preset]
    except KeyError:
        raise ValueError(f"unknown material preset {preset!r}; choose from {sorted(PRESETS)}") from None


def check_design(design: np.ndarray, n_faces: int, preset: MaterialPreset) -> np.ndarray:
    """Validate a design vector: (m,) float in [x_min, 1]; returns it as float64."""
    d = np.asarray(design, dtype=np.float64)
    if d.shape != (n_faces,):
        raise ValueError(f"design must have shape ({n_faces},), got {d.shape}")
    if not np.all(np.isfinite(d)) or d.min() < preset.x_min - 1e-12 or d.max() > 1 + 1e-12:
        raise ValueError(f"design values must lie in [x_min={preset.x_min}, 1]")
    return d


def garment_material(design: np.ndarray, preset: MaterialPreset) -> tuple[np.ndarray, np.ndarray]:
    """Per-face Young's modulus (Pa) and thickness (m) of the garment.

    design : (m,) in [x_min, 1].  Returns ``(Y, t)``, each (m,).
    """
    dp = np.asarray(design, dtype=np.float64) ** preset.penal
    y = dp * preset.young_reinforced + (1.0 - dp) * preset.young_cloth
    t = dp * preset.thick_reinforced + (1.0 - dp) * preset.thick_cloth
    return y, t


def log_stiffness_derivative(design: np.ndarray, preset: MaterialPreset) -> np.ndarray:
    """(m,) ``d log(Y t) / d d`` per garment face.

    At fixed positions a garment element's energy is ``E_e = W_hat(strain) * Y t A``, so
    its explicit design derivative is ``E_e * log_stiffness_derivative(d)``.
    """
    d = np.asarray(design, dtype=np.float64)
    p = preset.penal
    y, t = garment_material(d, preset)
    ddp = p * d ** (p - 1.0)
    dy = ddp * (preset.young_reinforced - preset.young_cloth)
    dt = ddp * (preset.thick_reinforced - preset.thick_cloth)
    return dy / y + dt / t


def clutch_material(activation: float, preset: MaterialPreset) -> tuple[float, float]:
    """Young's modulus (Pa) and thickness (m) of a clutch at activation ``g`` in [0, 1]."""
    g = float(activation)
    if not 0.0 <= g <= 1.0:
        raise ValueError(f"clutch activation must lie in [0, 1], got {g}")
    y = g * preset.young_clutch_on + (1.0 - g) * preset.young_clutch_off
    t = g * preset.thick_clutch_on + (1.0 - g) * preset.thick_clutch_off
    return y, t


def lame_plane_stress(young: np.ndarray, poisson: float) -> tuple[np.ndarray, np.ndarray]:
    """Plane-stress Lame parameters ``(mu, lambda)`` in Pa for Young's modulus ``young``."""
    young = np.asarray(young, dtype=np.float64)
    mu = young / (2.0 * (1.0 + poisson))
    lam = young * poisson / (1.0 - poisson**2)
    return mu, lam
