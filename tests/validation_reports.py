"""Are two runs of ``marine-fdi validate`` on the shipped datasets the same?  The check behind a change that must
leave the validation bit for bit (a move, a rename, a speed-up).

    python -m tests.validation_reports BEFORE_DIR AFTER_DIR

Each folder holds the outputs of the same commands run by two versions of the code, with the same file names:
``NAME.json`` (``--out``), ``NAME.md`` (``--markdown``) and any fitted-engine file (``--save-params``,
``*_fitted_engine.json``).  The JSON files are compared as loaded values, exactly, without what names the run rather
than the result: every ``seconds`` (wall time, the report's and its parts'), the report's ``dataset.path`` (where the
package is installed) and the fitted engine's ``provenance.date`` and ``provenance.command`` (the command line, with
its output paths); the Markdown files byte for byte.  Exit status 1 and the first differing keys on a difference.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

# left out of the comparison, they name the run and not the result: a key of this name anywhere (wall time) ...
TIME_KEY = "seconds"
# ... and these key paths at the top level and under "fitted_engine"
RUN_KEYS = (("dataset", "path"), ("provenance", "date"), ("provenance", "command"))


def _without_time(x: Any) -> Any:
    if isinstance(x, dict):
        return {k: _without_time(v) for k, v in x.items() if k != TIME_KEY}
    if isinstance(x, list):
        return [_without_time(v) for v in x]
    return x


def normalised(report: Any) -> Any:
    """``report`` without :data:`TIME_KEY` anywhere and without :data:`RUN_KEYS`."""
    if not isinstance(report, dict):
        return report
    out = _without_time(report)
    for obj in (out, out.get("fitted_engine")):
        if not isinstance(obj, dict):
            continue
        for keys in RUN_KEYS:
            parent = obj
            for k in keys[:-1]:
                parent = parent.get(k) if isinstance(parent, dict) else None
            if isinstance(parent, dict):
                parent.pop(keys[-1], None)
    return out


def differences(a: Any, b: Any, where: str = "", limit: int = 10) -> list[str]:
    """Where ``a`` and ``b`` differ (key paths), at most ``limit``."""
    out: list[str] = []
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                out.append(f"{where}/{k}: only in {'after' if k in b else 'before'}")
            else:
                out += differences(a[k], b[k], f"{where}/{k}", limit - len(out))
            if len(out) >= limit:
                break
    elif isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b)):
            out += differences(x, y, f"{where}[{i}]", limit - len(out))
            if len(out) >= limit:
                break
    elif a != b or type(a) is not type(b):
        out.append(f"{where}: {str(a)[:80]!r} != {str(b)[:80]!r}")
    return out[:limit]


def compare(before: Path, after: Path) -> list[str]:
    """Every difference between the two folders' reports (empty: the same)."""
    problems = []
    names = sorted(p.name for p in before.iterdir() if p.suffix in (".json", ".md"))
    if not names:
        return [f"{before}: no report"]
    for name in names:
        a, b = before / name, after / name
        if not b.is_file():
            problems.append(f"{name}: missing in {after}")
        elif name.endswith(".md"):
            if a.read_bytes() != b.read_bytes():
                problems.append(f"{name}: the Markdown differs")
        else:
            d = differences(normalised(json.loads(a.read_text())), normalised(json.loads(b.read_text())))
            problems += [f"{name}: {x}" for x in d]
    return problems


if __name__ == "__main__":
    before_dir, after_dir = (Path(x) for x in sys.argv[1:3])
    found = compare(before_dir, after_dir)
    compared = sorted(p.name for p in before_dir.iterdir() if p.suffix in (".json", ".md"))
    print(f"compared {len(compared)} files: {', '.join(compared)}")
    print("\n".join(found) if found else "identical (JSON without the run's path, time, date and command; Markdown)")
    sys.exit(1 if found else 0)
