"""Progress bars on stderr that count episodes (or scenarios), resumable and quiet in log files.

While a bar is shown, whatever else is written to stderr (Python warnings, log records of
third-party libraries such as Ray's) is printed as whole lines above the bar, never into it.
"""

from __future__ import annotations

import io
import logging
import sys

__all__ = ["progress_bar"]


class _AboveBar(io.TextIOBase):
    """A text stream that prints whole lines above the progress bars on ``stream`` (``tqdm.write``)."""

    def __init__(self, stream) -> None:
        super().__init__()
        self.stream = stream
        self.pending = ""

    def writable(self) -> bool:
        return True

    def write(self, text: str) -> int:
        from tqdm import tqdm

        *lines, self.pending = (self.pending + text).split("\n")
        for line in lines:
            tqdm.write(line, file=self.stream)
        return len(text)

    def flush(self) -> None:
        if self.pending:
            from tqdm import tqdm

            tqdm.write(self.pending, file=self.stream)
            self.pending = ""
        self.stream.flush()

    def isatty(self) -> bool:
        return _isatty(self.stream)


class _Redirect:
    """``sys.stderr`` and the log handlers writing to it go through an :class:`_AboveBar` until
    :meth:`restore` (handlers created meanwhile, e.g. by a library imported under the bar, pick up
    the redirected ``sys.stderr`` themselves)."""

    def __init__(self, stream) -> None:
        self.stream = stream
        self.above = _AboveBar(stream)
        self.handlers = []
        loggers = [logging.getLogger()] + [
            lg for lg in logging.Logger.manager.loggerDict.values() if isinstance(lg, logging.Logger)
        ]
        for lg in loggers:
            for h in lg.handlers:
                if isinstance(h, logging.StreamHandler) and h.stream is stream:
                    h.setStream(self.above)
                    self.handlers.append(h)
        self.saved_stderr, sys.stderr = sys.stderr, self.above

    def restore(self) -> None:
        self.above.flush()
        if sys.stderr is self.above:
            sys.stderr = self.saved_stderr
        for h in self.handlers:
            if h.stream is self.above:
                h.setStream(self.stream)


class _Bar:
    """A tqdm bar in (fractional) episodes: it never passes its total, and prints its final state
    exactly once (on :meth:`close`)."""

    def __init__(self, bar, redirect: _Redirect | None = None) -> None:
        self.bar = bar
        self.redirect = redirect

    def _set(self, n: float) -> None:
        bar = self.bar
        n = min(max(float(n), 0.0), float(bar.total))
        if n >= bar.total - 1e-6:  # done (up to rounding): the final line is printed once, by close()
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
        if self.redirect is not None:
            self.redirect.restore()
            self.redirect = None


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

    stream = sys.stderr
    bar = tqdm(
        total=total,
        initial=done,
        desc=desc,
        unit=unit,
        file=stream,
        mininterval=0.1 if _isatty(stream) else 10.0,
        bar_format="{l_bar}{bar}| {n:.1f}/{total_fmt} " + unit + "s [{elapsed}<{remaining}]",
    )
    return _Bar(bar, _Redirect(stream))
