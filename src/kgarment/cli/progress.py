"""Progress of long commands: a rich progress bar on a terminal, plain lines elsewhere.

rich draws its bars only on a terminal; with standard output a file or a pipe (``nohup``,
CI, a batch queue, ``| tee``) it printed nothing until the end, so a design or reproduction
of hours left an empty log.  :class:`LineProgress` takes the bar's place there: the same
calls (``add_task``, ``update``), one line per task at its first update, then at most one
every :data:`EVERY_S` seconds, and the last state of every task at the end, each line with
the time elapsed and an ETA from the mean time per step so far.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Self

from kgarment.io import seconds_left

EVERY_S = 30.0  # seconds between two lines of one task


def on_terminal() -> bool:
    """Whether standard output is a terminal (where rich draws its bars)."""
    isatty = getattr(sys.stdout, "isatty", None)
    return bool(isatty and isatty())


def progress_bars(head, label: Callable[[dict], str], quiet: bool):
    """rich's bars on a terminal (disabled when ``quiet``): the ``head`` columns, then the bar,
    the task's description, the time elapsed and the ETA; else a :class:`LineProgress` with
    ``label``: the bars of every long command."""
    if quiet or on_terminal():
        from rich.progress import (
            BarColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        return Progress(*head, BarColumn(), TextColumn("{task.description}"), TimeElapsedColumn(), TextColumn("ETA"),
                        TimeRemainingColumn(), disable=quiet)
    return LineProgress(label)


def clock_text(seconds: float | None) -> str:
    """``seconds`` as H:MM:SS (``-:--:--`` when unknown)."""
    if seconds is None or not math.isfinite(seconds) or seconds < 0:
        return "-:--:--"
    s = round(seconds)
    return f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}"


@dataclass
class _Task:
    fields: dict
    total: float | None
    completed: float
    description: str
    started: float
    first: float  # ``completed`` at the start (a resumed run's iterations do not count for the rate)
    updated_at: float = 0.0  # the time of the last update (what the line at the end reports)
    printed_at: float | None = None
    dirty: bool = True


class LineProgress:
    """Progress as lines of text, with the calls of ``rich.progress.Progress`` that kgarment uses.

    label : the start of each line from the task's fields and its ``completed`` and ``total``
    (a dict), e.g. ``lambda t: f"it {t['completed']:>3}"``;  every : seconds between two lines of
    one task;  clock : seconds (monotonic; a test's fake clock);  write : where a line goes
    (default: print to standard output, flushed).
    """

    def __init__(self, label: Callable[[dict], str], every: float = EVERY_S,
                 clock: Callable[[], float] = time.monotonic, write: Callable[[str], None] | None = None):
        self.label = label
        self.every = every
        self.clock = clock
        self.write = write or (lambda line: print(line, flush=True))
        self.tasks: list[_Task] = []

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        for t in self.tasks:  # the last state of every task, once
            if t.dirty and t.printed_at is not None:
                self._line(t)

    def add_task(self, description: str = "", total: float | None = None, completed: float = 0,
                 **fields) -> int:
        now = self.clock()
        self.tasks.append(_Task(fields, total, completed, description, now, completed))
        return len(self.tasks) - 1

    def update(self, task: int, *, completed: float | None = None, total: float | None = None,
               description: str | None = None, **fields) -> None:
        t = self.tasks[task]
        if completed is not None:
            t.completed = completed
        if total is not None:
            t.total = total
        if description is not None:
            t.description = description
        t.fields.update(fields)
        t.dirty = True
        now = t.updated_at = self.clock()
        if t.printed_at is None or now - t.printed_at >= self.every:
            self._line(t)

    @staticmethod
    def _eta(t: _Task) -> float | None:
        """Seconds left for task ``t`` at its last update, at its mean time per step (None: unknown)."""
        if t.total is None:
            return None
        return seconds_left(t.updated_at - t.started, t.completed - t.first, t.total - t.first)

    def _line(self, t: _Task) -> None:
        now = t.updated_at
        head = self.label({**t.fields, "completed": t.completed, "total": t.total})
        eta = self._eta(t)
        tail = f"{clock_text(now - t.started)} elapsed" + ("" if t.total is None else f", ETA {clock_text(eta)}")
        self.write("  ".join(s for s in (head, t.description, tail) if s))
        t.printed_at, t.dirty = self.clock(), False
