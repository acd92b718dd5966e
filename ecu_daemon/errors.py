"""The errors a command reports as one line and an exit status, without a traceback.

Here and not in the CLI so that library modules (recorder, replay, daemon) raise them without
importing the command line.
"""
from __future__ import annotations


class UserError(Exception):
    """An expected failure reported as one line (bad file, bad option); exit status 2."""

    exit_code = 2


class UnusableInputError(UserError):
    """A run that went to the end but a required input never gave a usable sample; exit status 3."""

    exit_code = 3

    def __init__(self, message: str, summary: dict | None = None):
        super().__init__(message)
        self.summary = summary
