"""Garments: regions of the body surface, subdivided, with attachment rings."""

from kgarment.garment.garment import (
    ALIASES,
    Garment,
    garment_from_mask,
    load_face_mask,
    make_garment,
    template_names,
)
from kgarment.garment.templates import GarmentTemplate, builtin_templates

__all__ = [
    "ALIASES", "Garment", "GarmentTemplate", "builtin_templates", "garment_from_mask", "load_face_mask",
    "make_garment", "template_names",
]
