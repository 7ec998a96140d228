"""Progress bars on stderr that count episodes (or scenarios), resumable and quiet in log files."""

from __future__ import annotations

import sys

__all__ = ["progress_bar"]


class _Bar:
    """A tqdm bar in (fractional) episodes: it never passes its total, and prints its final state
    exactly once (on :meth:`close`)."""

    def __init__(self, bar) -> None:
        self.bar = bar

    def _set(self, n: float) -> None:
        bar = self.bar
        n = min(max(float(n), 0.0), float(bar.total))
        if n >= bar.total - 1e-6:   # done (up to rounding): the final line is printed once, by close()
            bar.n = bar.total
            return
        bar.n = n
        bar.update(0)  # redraws when tqdm's mininterval has passed

    def advance(self, x: float) -> None:
        if self.bar is not None and x:
            self._set(self.bar.n + x)

    def set_done(self, n: float) -> None:
        if self.bar is not None:
            self._set(n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def _isatty(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


def progress_bar(total: int, done: int, desc: str, enabled: bool = True, unit: str = "episode") -> _Bar:
    """A progress bar on stderr counting episodes, starting at ``done``; says "resuming at
    done/total" when done > 0 (also without a bar).  Off a terminal (a log file) it redraws at
    most every 10 s."""
    if done:
        print(f"{desc}: resuming at {done}/{total}", file=sys.stderr)
    if not enabled:
        return _Bar(None)
    from tqdm import tqdm

    return _Bar(tqdm(total=total, initial=done, desc=desc, unit=unit, file=sys.stderr,
                     mininterval=0.1 if _isatty(sys.stderr) else 10.0,
                     bar_format="{l_bar}{bar}| {n:.1f}/{total_fmt} " + unit + "s [{elapsed}<{remaining}]"))
