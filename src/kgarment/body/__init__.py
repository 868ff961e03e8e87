"""Bodies and motions."""

from kgarment.body.anny_backend import Phenotype, load_anny_body
from kgarment.body.meshseq import load_mesh_sequence
from kgarment.body.model import Body, vertex_normals
from kgarment.body.motions import PAPER_MOTIONS, Motion, MotionLibrary, Rotation, builtin_motions

__all__ = [
    "Body", "Motion", "MotionLibrary", "PAPER_MOTIONS", "Phenotype", "Rotation",
    "builtin_motions", "load_anny_body", "load_mesh_sequence", "vertex_normals",
]
