"""Electrostatic clutches: specification, surface walk, strip mesh, files and layouts."""

from kgarment.clutch.strip import ClutchStrip

__all__ = ["ClutchStrip"]
