"""The BESO optimiser: the update rule, filters and schedule (``beso``), how the states'
energies make the objective (``objective``), the connected update (``connect``), the step
guard (``guard``), one iteration as pure steps (``loop``), coarse-to-fine (``refine``),
the check over the motion from rest (``motion_start``) and its settings (``setup``)."""

from kgarment.optimize.beso import BesoParams, update_design
from kgarment.optimize.loop import LoopState, initial_state, iterate, run_loop
from kgarment.optimize.objective import OBJECTIVES
from kgarment.optimize.setup import BesoSetup, DesignSetup, setup_from_problem

__all__ = ["OBJECTIVES", "BesoParams", "BesoSetup", "DesignSetup", "LoopState", "initial_state", "iterate",
           "run_loop", "setup_from_problem", "update_design"]
