"""Automatic design: BESO with the ON/OFF energy-differential objective."""

from kgarment.design.beso import BesoParams, update_design
from kgarment.design.objective import OBJECTIVES

__all__ = ["BesoParams", "OBJECTIVES", "update_design"]
