"""Output paths of the long-running commands, and what tells a resumed run from another one.

``prepare_out`` creates the parent of an output path when it is missing, never more levels (a typo in a
long path is an error, not a tree of new folders); ``differing_fields`` says field by field why a kept
partial file belongs to another run.
"""

from __future__ import annotations

from pathlib import Path

from .errors import UsageError

__all__ = ["prepare_out", "check_suffix", "differing_fields"]


def prepare_out(path: "str | Path", option: str = "--out", *, is_dir: bool = True, create: bool = True) -> Path:
    """Create the parent of ``path`` if missing (one level only) and, for a folder, ``path`` itself.

    ``create=False`` only checks (``ValueError`` naming ``option``): a command that still has to
    validate other input checks its output path first and creates it when it writes, so a
    failing command leaves no new folder behind."""
    p = Path(path)
    parent = p.parent
    if not parent.exists():
        if not parent.parent.is_dir():
            raise UsageError(
                f"{option}: folder {str(parent.parent)!r} does not exist (only the parent of {option} is created)"
            )
        _check_writable(parent.parent, option, p)
        if create:
            parent.mkdir()
    elif not parent.is_dir():
        raise UsageError(f"{option}: {str(parent)!r} is not a folder")
    if is_dir:
        if p.exists() and not p.is_dir():
            raise UsageError(f"{option} must be a folder, got the file {str(p)!r}")
        if p.is_dir():
            _check_writable(p, option, p)
        elif parent.is_dir():
            _check_writable(parent, option, p)
        if create:
            p.mkdir(exist_ok=True)
    elif p.is_dir():
        raise UsageError(f"{option} must be a file path, got the folder {str(p)!r}")
    elif parent.is_dir():
        _check_writable(parent, option, p)
    return p


def _check_writable(folder: Path, option: str, path: Path) -> None:
    """A :class:`UsageError` naming ``option`` when no file can be created in ``folder`` (tried with a
    temporary file, removed at once: permissions alone do not tell, e.g. for root or a read-only mount)."""
    import tempfile

    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as e:
        raise UsageError(
            f"{option} {str(path)!r}: cannot write in the folder {str(folder)!r} ({e.strerror or e})"
        ) from None


def check_suffix(path: "str | Path", option: str, allowed: tuple[str, ...], what: str) -> Path:
    """``path`` if its extension is one of ``allowed`` (the formats it can be written in), else a
    :class:`UsageError` naming the option, the extensions and what the file holds."""
    p = Path(path)
    if p.suffix.lower() not in allowed:
        raise UsageError(
            f"{option} {str(p)!r}: {what} ends in {' or '.join(allowed)} (the format it is written in), "
            f"got {p.suffix or 'no extension'!r}"
        )
    return p


def differing_fields(old, new, prefix: str = "") -> str:
    """What differs between two JSON objects, field by field: ``agent: 'random' there, 'reference'
    here; seed_offset: 0 there, 1 here`` (for "this partial file belongs to another run" errors)."""
    if not isinstance(old, dict) or not isinstance(new, dict):
        return f"{prefix or 'header'}: {_short(old)} there, {_short(new)} here"
    parts = []
    for k in list(new) + [k for k in old if k not in new]:
        name = f"{prefix}.{k}" if prefix else str(k)
        if k not in old:
            parts.append(f"{name}: missing there, {_short(new[k])} here")
        elif k not in new:
            parts.append(f"{name}: {_short(old[k])} there, missing here")
        elif old[k] != new[k]:
            parts.append(
                differing_fields(old[k], new[k], name)
                if isinstance(old[k], dict) and isinstance(new[k], dict)
                else f"{name}: {_short(old[k])} there, {_short(new[k])} here"
            )
    return "; ".join(parts) or "no field differs"


def _short(v, width: int = 60) -> str:
    text = repr(v)
    return text if len(text) <= width else text[: width - 3] + "..."
