"""The errors uavlink raises on purpose, so the CLI can tell a user's mistake from a bug.

``UserError`` (bad input: a flag, a config value, a policy or key file) is what the command line
turns into one line on stderr and exit status 2; anything else is a bug and keeps its traceback.
It subclasses ``ValueError`` so library callers that catch ``ValueError`` keep working.
"""

from __future__ import annotations


class UserError(ValueError):
    """Bad input from the user; the message is one line that says what and how to fix it."""


class ConfigError(UserError):
    """A config value that makes no physical sense or names an unknown field."""
