"""The ``marine-fdi`` command line: every argument parser of the package lives here.

Library functions elsewhere take typed arguments and raise :mod:`marine_fdi_env.errors` exceptions; the
modules of this package parse argv, call them, and turn a refusal into one line on stderr and exit code 2.
Nothing in the package imports this one.
"""

from .main import build_parser, console_main, main

__all__ = ["main", "console_main", "build_parser"]
