"""Errors raised by :mod:`kgarment.clutch`."""

from __future__ import annotations

from kgarment.errors import KgarmentError


class ClutchError(KgarmentError):
    """A clutch cannot be placed: bad specification, or it does not fit on the garment.

    A ``ValueError`` (through :class:`kgarment.errors.KgarmentError`, which the CLI prints
    in one line). The message is one line and names the clutch (and the field or file).
    """
