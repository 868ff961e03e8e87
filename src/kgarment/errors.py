"""User-facing errors.

Every error a user can fix (a missing file, an unknown motion, a value out of range) is a
:class:`KgarmentError`; the CLI prints its one-line message and exits with status 2.
"""

from __future__ import annotations


class KgarmentError(ValueError):
    """A problem with the user's input, explained in one line."""


def unknown(kind: str, name: str, valid) -> KgarmentError:
    """An error for an unknown name, listing the valid ones."""
    valid = sorted(valid)
    return KgarmentError(f"unknown {kind} {name!r}; valid: {', '.join(map(str, valid))}")


class Cancelled(Exception):
    """A long computation (an evaluation, a design run) was asked to stop between steps;
    what it computed so far is kept (a run folder stays resumable)."""
