"""Design runs: the one run driver (problem -> finished run folder: ``driver``), run folders,
checkpoints and design sources (``run``), the coarse levels of a coarse-to-fine run
(``coarse``), the iteration a run reports (``reported``), its final files and renders
(``report``) and one design for a size range (``sizes``).

The stages below it: :mod:`kgarment.case` (the solvable problem on a body),
:mod:`kgarment.evaluate` (measuring a design) and :mod:`kgarment.optimize` (BESO).
"""

from kgarment.design.driver import DesignRun, finish, open_run
from kgarment.design.run import (
    DesignSource,
    load_design,
    load_design_history,
    parse_design_source,
    run_status,
)

__all__ = ["DesignRun", "DesignSource", "finish", "load_design", "load_design_history", "open_run",
           "parse_design_source", "run_status"]
