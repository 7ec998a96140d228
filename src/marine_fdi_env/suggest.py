""" "Did you mean ...?" for a misspelled name (a fault id, suite, preset, scenario, agent)."""

from __future__ import annotations

import difflib
from typing import Iterable

__all__ = ["did_you_mean"]


def did_you_mean(word: object, choices: Iterable[str], n: int = 2) -> str:
    """`` (did you mean 'X'?)`` with the closest of ``choices`` to ``word`` (ignoring case), or
    ``""`` when none is close (difflib ratio >= 0.6) or ``word`` is not a string."""
    if not isinstance(word, str) or not word:
        return ""
    choices = list(choices)
    by_lower = {c.lower(): c for c in choices}
    if word.lower() in by_lower:  # only the case differs
        return f" (did you mean {by_lower[word.lower()]!r}?)"
    hits = difflib.get_close_matches(word.lower(), list(by_lower), n=n, cutoff=0.6)
    if not hits:
        return ""
    return " (did you mean " + " or ".join(repr(by_lower[h]) for h in hits) + "?)"
