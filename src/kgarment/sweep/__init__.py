"""Sweeps: many variations of a problem (a grid of field values or a list of runs), each
an ordinary run folder made by the one run driver, run side by side on Ray, resumable,
summed up in a table and plots.

``spec`` reads and validates a sweep file into tasks; ``folder`` keeps the sweep folder
(what it ran, each task's record); ``execute`` runs the tasks on Ray (imported only
there: Ray is the optional ``sweep`` extra); ``table`` and ``plot`` write ``sweep.csv``,
``sweep.md`` and ``sweep.png``.
"""

from kgarment.sweep.folder import SweepFolder, open_folder, summarise_run
from kgarment.sweep.spec import Sweep, Task, load_sweep, task_name

__all__ = ["Sweep", "SweepFolder", "Task", "load_sweep", "open_folder", "summarise_run", "task_name"]
