"""Measuring a design: the one evaluator (rho ON/OFF, stored energies, the structure),
the load each clutch carries, the force over the motion from rest, the control plan of
which clutches to switch on for which motion, and the control screen before a design."""

from kgarment.evaluate.evaluator import DesignEvaluation, Evaluator, StateEvaluation

__all__ = ["DesignEvaluation", "Evaluator", "StateEvaluation"]
