"""The solvable problem on a body: a garment with its clutches as a simulator model, the
motions and the states they are solved in (:class:`Case`), the subdivision levels, the
wearers of a multi-body design, the frames of a motion, the store of equilibria, the
activation continuation and the starts of a design's equilibrium."""

from kgarment.case.setup import Case, activation_vectors, case_from_problem
from kgarment.case.states import LOCK, SOLO, StateKey, states_needed

__all__ = ["LOCK", "SOLO", "Case", "StateKey", "activation_vectors", "case_from_problem", "states_needed"]
