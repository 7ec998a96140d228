"""Every command written in the README and docs names a command that exists and options it accepts.

Commands are read from the README's and ``docs/*.md``'s code blocks and inline code: ``marine-fdi COMMAND
...`` and ``python -m studies.PART.STUDY ...``.  Each must answer ``--help``, and every ``--option`` written
after it must be one of the options its help lists (a renamed or removed option in a command people copy
fails here).  What the commands compute is checked by the tests of each command; the README's own
commands also run end to end (``test_readme.py``).
"""

from __future__ import annotations

import contextlib
import io
import re
import runpy
import sys
from functools import lru_cache

import pytest

from tests.paths import ROOT

_DOCS = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
_CMD = re.compile(r"(marine-fdi [a-z][a-z-]*|python -m studies(?:\.[a-z_]+)+)((?:[ \t]+[^\s`|;]+)*)")
# options written as an example of what a command refuses, not as a way to call it
_REFUSED = {"--engines", "--episodes"}


def _commands() -> dict[str, set[str]]:
    found: dict[str, set[str]] = {}
    for doc in _DOCS:
        for line in doc.read_text(encoding="utf-8").splitlines():
            for m in _CMD.finditer(line):
                cmd, rest = m.group(1), m.group(2)
                if cmd.startswith("marine-fdi ") and cmd.split()[1] in ("error", "evaluate:"):
                    continue
                found.setdefault(cmd, set()).update(re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*)", rest))
    return found


COMMANDS = _commands()


@lru_cache(maxsize=None)
def _help(cmd: str) -> str:
    """The command's ``--help`` text, run in this process."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        if cmd.startswith("marine-fdi "):
            from marine_fdi_env.cli import main

            code = main([*cmd.split()[1:], "--help"])
        else:
            name = cmd.split()[-1]
            saved, imported = sys.argv, sys.modules.pop(name, None)  # run as __main__, not over an import of it
            sys.argv = [name, "--help"]
            try:
                runpy.run_module(name, run_name="__main__")
                code = 0
            except SystemExit as e:
                code = e.code or 0
            finally:
                sys.argv = saved
                if imported is not None:
                    sys.modules[name] = imported
    assert code == 0, f"{cmd} --help failed: {err.getvalue()[-500:]}"
    return out.getvalue()


def test_the_docs_name_commands():
    assert "marine-fdi evaluate" in COMMANDS and any(c.startswith("python -m studies.") for c in COMMANDS)


@pytest.mark.parametrize("cmd", sorted(COMMANDS))
def test_every_documented_command_and_option_exists(cmd):
    text = _help(cmd)
    missing = sorted(o for o in COMMANDS[cmd] if o not in text and o not in _REFUSED)
    assert not missing, f"{cmd}: the docs pass {missing}, which its --help does not list"
