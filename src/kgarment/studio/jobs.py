"""Background jobs (simulations, optimisations) that never touch the edited state.

A :class:`Job` runs ``work(job)`` in a daemon thread. ``work`` reads a frozen copy of
what it needs, reports progress with ``job.report(text)``, checks ``job.cancelled`` (and
raises :class:`kgarment.errors.Cancelled` to stop), and returns a result; the job then calls ``on_done(result)``, or ``on_error(message)`` with a
one-line message if it raised (user errors as they are, anything else as "what failed:
type: reason", with the traceback in the log). Either way the studio's edits stay as
they were: jobs hand results over, they do not write into the state.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Generic, TypeVar

from kgarment.errors import Cancelled, KgarmentError

log = logging.getLogger(__name__)
T = TypeVar("T")


class Job(Generic[T]):
    """One background computation (see the module docstring).

    status : "idle" | "running" | "done" | "failed" | "cancelled"; message : the last
    progress or error text; result : what ``work`` returned (when done).
    """

    def __init__(self, name: str, work: Callable[[Job[T]], T],
                 on_done: Callable[[T], None] | None = None,
                 on_error: Callable[[str], None] | None = None,
                 on_report: Callable[[str], None] | None = None,
                 on_cancel: Callable[[], None] | None = None):
        self.name = name
        self._work = work
        self._on_done, self._on_error = on_done, on_error
        self._on_report, self._on_cancel = on_report, on_cancel
        self._cancel = threading.Event()
        self._thread: threading.Thread | None = None
        self.status = "idle"
        self.message = ""
        self.result: T | None = None
        self.started = 0.0

    @property
    def cancelled(self) -> bool:
        return self._cancel.is_set()

    @property
    def running(self) -> bool:
        return self.status == "running"

    def report(self, text: str) -> None:
        self.message = text
        log.info("%s: %s", self.name, text)
        if self._on_report is not None:
            _safe(self._on_report, text)

    def start(self) -> Job[T]:
        if self._thread is not None:
            raise RuntimeError(f"job {self.name} was started already")
        self.status, self.started = "running", time.time()
        self._thread = threading.Thread(target=self._run, name=f"kgarment-studio-{self.name}", daemon=True)
        self._thread.start()
        return self

    def cancel(self) -> None:
        self._cancel.set()

    def wait(self, timeout: float | None = None) -> bool:
        """Wait for the job to end; False on timeout."""
        if self._thread is not None:
            self._thread.join(timeout)
            return not self._thread.is_alive()
        return True

    def _run(self) -> None:
        try:
            result = self._work(self)
        except Cancelled:
            self.status, self.message = "cancelled", f"{self.name} stopped"
            if self._on_cancel is not None:
                _safe(self._on_cancel)
            return
        except KgarmentError as exc:
            self._fail(f"{self.name} failed: {exc}")
            return
        except Exception as exc:  # a crash in the numerics must not take the page down
            log.exception("%s failed", self.name)
            self._fail(f"{self.name} failed: {type(exc).__name__}: {exc}")
            return
        self.result, self.status = result, "done"
        self.message = f"{self.name} done in {time.time() - self.started:.1f} s"
        if self._on_done is not None:
            _safe(self._on_done, result)

    def _fail(self, message: str) -> None:
        self.status, self.message = "failed", message
        if self._on_error is not None:
            _safe(self._on_error, message)


def _safe(fn, *args) -> None:
    try:
        fn(*args)
    except Exception:  # a failing page update must not kill the worker thread silently
        log.exception("studio callback failed")
