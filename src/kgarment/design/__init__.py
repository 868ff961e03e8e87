"""Automatic design: BESO with the ON/OFF energy-differential objective.

``beso`` (the update rule, filters, schedule), ``objective`` (how states combine),
``metrics`` (rho, islands, clutch ends), ``setup`` (the frozen precomputed setup),
``loop`` (one iteration as pure steps), ``evaluate`` (the one design evaluator), ``run``
(run folders, checkpoints, design sources), ``report`` (final files and renders) and
``driver`` (the one run driver: problem -> finished run folder).
"""

from kgarment.design.beso import BesoParams, design_values, update_design
from kgarment.design.driver import DesignRun, finish, open_run
from kgarment.design.evaluate import DesignEvaluation, Evaluator, StateEvaluation
from kgarment.design.loop import LoopState, initial_state, iterate, run_loop
from kgarment.design.objective import OBJECTIVES
from kgarment.design.run import (
           DesignSource,
           load_design,
           load_design_history,
           parse_design_source,
           run_status,
)
from kgarment.design.setup import DesignSetup, setup_from_problem

__all__ = ["OBJECTIVES", "BesoParams", "DesignEvaluation", "DesignRun", "DesignSetup", "DesignSource", "Evaluator",
           "LoopState", "StateEvaluation", "design_values", "finish", "initial_state", "iterate", "load_design", "load_design_history",
           "open_run", "parse_design_source", "run_loop", "run_status", "setup_from_problem", "update_design"]
