"""The exceptions marine_fdi_env raises when it refuses a user's input.

Every message is one line (a measured-data file: one line per problem) naming the option, file or
field and what is allowed.  All are :class:`ValueError` subclasses, as are the argument checks of the
library's functions, so ``except ValueError`` catches every refusal; the ``marine-fdi`` command turns
them into a message on stderr and exit code 2.

========================  =================================================================
class                     refused
========================  =================================================================
:class:`MarineFDIError`   the base of the kinds below
:class:`UsageError`       a command-line option or argument (value, combination, output path)
:class:`DataFileError`    the content of a file: predictions, results, run and suite files
:class:`DatasetError`     measured engine data; ``problems`` lists every error and warning
:class:`MissingExtra`     an option that needs an optional dependency that is not installed
========================  =================================================================
"""

from __future__ import annotations

from typing import Protocol, Sequence

__all__ = ["MarineFDIError", "UsageError", "DataFileError", "DatasetError", "MissingExtra", "EXTRAS"]

# optional module -> the extra of pyproject.toml that installs it
EXTRAS: dict[str, str] = {
    "matplotlib": "plots",
    "pyarrow": "parquet",
    "ray": "ray",
    "torch": "train",
    "stable_baselines3": "train",
    "rl_zoo3": "zoo",
    "minari": "minari",
    "pettingzoo": "multiagent",
}


class MarineFDIError(ValueError):
    """Input marine_fdi_env refuses; the message names what was refused and what is allowed."""


class UsageError(MarineFDIError):
    """A command-line option or argument: its value, a combination of options, an output path."""


class DataFileError(MarineFDIError):
    """The content of a file (predictions, results, run or suite file); the message names the file and
    where in it (line, row, column or field)."""


class _Problem(Protocol):
    severity: str


class DatasetError(DataFileError):
    """Measured engine data with errors; ``problems`` holds every error and warning found (all are
    checked before this is raised), and the message lists them, one per line."""

    def __init__(self, source: str, problems: Sequence[_Problem]):
        self.problems = list(problems)
        errors = [p for p in problems if p.severity == "error"]
        lines = [f"{source}: {len(errors)} error{'s' if len(errors) != 1 else ''} in the measured data:"]
        lines += [f"  - {p}" for p in errors]
        warns = [p for p in problems if p.severity == "warning"]
        if warns:
            lines.append(f"  and {len(warns)} warning{'s' if len(warns) != 1 else ''}:")
            lines += [f"  - {p}" for p in warns]
        super().__init__("\n".join(lines))


class MissingExtra(MarineFDIError):
    """An option needs an optional dependency: "WHAT needs MODULE: pip install 'marine-fdi-env[EXTRA]'"
    (and `` (HINT)``, e.g. an option that does without it)."""

    def __init__(self, module: str, what: str, hint: str = ""):
        top = module.split(".")[0]
        self.module, self.extra = top, EXTRAS.get(top, "dev")
        super().__init__(
            f"{what} needs {top}: pip install 'marine-fdi-env[{self.extra}]'" + (f" ({hint})" if hint else "")
        )


def require_extra(module: str, what: str) -> None:
    """Raise :class:`MissingExtra` when ``module`` cannot be imported; called before a command does any
    work, so a missing extra costs nothing."""
    import importlib

    try:
        importlib.import_module(module)
    except ImportError:
        raise MissingExtra(module, what) from None
