""" "Did you mean ...?" for a misspelled name (a fault id, suite, preset, scenario, agent)."""

from __future__ import annotations

import difflib
from typing import Iterable, Mapping, TypeVar

__all__ = ["did_you_mean", "lookup"]

T = TypeVar("T")


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


def lookup(table: Mapping[str, T], key: object, what: str) -> T:
    """``table[key]``; else ``ValueError("unknown WHAT 'KEY' (did you mean ...?); allowed: A, B, ...")``."""
    try:
        return table[key]  # type: ignore[index]
    except (KeyError, TypeError):
        raise ValueError(
            f"unknown {what} {key!r}{did_you_mean(str(key), tuple(table))}; allowed: {', '.join(table)}"
        ) from None
