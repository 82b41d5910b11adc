"""Errors that carry one line for the user.

Every error a user can cause (bad files, bad options) is a :class:`SimcredError`, a ``ValueError``
whose message is a single line naming the file, run, column or position at fault. The CLI prints
that line in red and exits with code 2; it never shows a traceback for these.
"""

from __future__ import annotations


class SimcredError(ValueError):
    """Bad input: the message is one line that names the culprit."""

    def __init__(self, message: str) -> None:
        super().__init__(" ".join(message.splitlines()))


class TraceSetError(SimcredError):
    """A trace set (file, directory, run or column) is missing, malformed or invalid."""


class OptionError(SimcredError):
    """An option is outside its domain (e.g. ``bins < 2``, ``alpha`` not in (0, 1))."""


class MissingDependencyError(SimcredError):
    """A program or package a command needs is not installed (e.g. SUMO): the message names it
    and how to install it; a user's environment, not a defect of simcred."""
