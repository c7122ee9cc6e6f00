"""The errors uavlink raises on purpose, so the CLI can tell a user's mistake from a bug.

``UserError`` (bad input: a flag, a config value, a policy or key file) is what the command line
turns into one line on stderr and exit status 2; ``LinkError`` (a lost or refusing vehicle) is one
line and exit status 1; anything else is a bug and keeps its traceback.
It subclasses ``ValueError`` so library callers that catch ``ValueError`` keep working.
"""

from __future__ import annotations

import argparse


class UserError(ValueError):
    """Bad input from the user; the message is one line that says what and how to fix it."""


class ConfigError(UserError):
    """A config value that makes no physical sense or names an unknown field."""


class LinkError(RuntimeError):
    """The vehicle did not answer or refused; the message says what and why. Declared here, not in
    ``uavlink.flight.link``, so the CLI can catch it (exit status 1) without importing pymavlink."""


# The optional packages and the extra that installs each (pyproject.toml's optional-dependencies).
EXTRA_OF_MODULE = {
    "torch": "train",
    "stable_baselines3": "train",
    "tensorboard": "train",
    "tqdm": "train",
    "rich": "train",
    "onnxruntime": "fly",
    "pymavlink": "fly",
    "onnx": "export",
    "matplotlib": "plot",
    "distributed": "sweep",
    "dask": "sweep",
    "tomli": "sweep",
    "pettingzoo": "fleet",
}


def missing_extra(exc: ModuleNotFoundError) -> str | None:
    """One line naming the extra that installs the missing module, or None when it is not optional
    (then the missing module is a bug or a broken install, and keeps its traceback)."""
    module = (exc.name or "").split(".")[0]
    extra = EXTRA_OF_MODULE.get(module)
    return (
        None
        if extra is None
        else f"this needs {module}, which is optional: pip install 'uavlink[{extra}]'"
    )


def require(module: str) -> None:
    """Import an optional module now, or raise a ``UserError`` with its install line: for work whose
    last step needs it, so that nothing is left half-written."""
    import importlib

    try:
        importlib.import_module(module)
    except ModuleNotFoundError as exc:
        raise UserError(missing_extra(exc) or f"this needs {module}") from None


class OneLineParser(argparse.ArgumentParser):
    """argparse with one-line errors, as every other user error here (argparse's own prints the whole
    usage first): ``PROG: error: MESSAGE (see PROG --help)``, exit status 2. Used by ``uavlink`` (its
    sub-commands' parsers are of the same class: ``add_subparsers`` uses it) and ``sitl-stub``."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")
