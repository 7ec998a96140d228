"""A progress line for Stable-Baselines3 training: what a long ``model.learn`` has done so far.

SB3's own ``progress_bar=True`` needs ``tqdm`` and ``rich`` (``stable-baselines3[extra]``); this callback needs
neither and prints plain lines, which read the same in a terminal, a log file and a notebook::

    model.learn(total_timesteps=1_000_000, callback=ProgressLine())
    # ppo: 245,760/1,000,000 steps (25 %), 3.1 min, reward per decision -0.012 since the last line
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import unwrap_vec_normalize

__all__ = ["ProgressLine"]


class ProgressLine(BaseCallback):
    """One line on ``stream`` (default stderr) every ``every_s`` seconds of wall time and when training ends:
    steps done of the total, the minutes since ``learn`` started, and the mean reward per decision since the
    previous line (the environment's own reward, before a ``VecNormalize``).  It reads and never changes
    anything: a run with it is the run without it, step for step."""

    def __init__(self, every_s: float = 60.0, stream: TextIO | None = None, prefix: str = "ppo"):
        super().__init__()
        if not every_s > 0:
            raise ValueError(f"every_s must be > 0, got {every_s!r}")
        self.every_s, self.stream, self.prefix = float(every_s), stream, prefix
        self._t0 = self._last = 0.0
        self._sum, self._n = 0.0, 0

    def _on_training_start(self) -> None:
        self._t0 = self._last = time.perf_counter()

    def _on_step(self) -> bool:
        norm = unwrap_vec_normalize(self.training_env)
        rewards = norm.get_original_reward() if norm is not None else self.locals.get("rewards")
        if rewards is not None:
            self._sum += float(sum(rewards))
            self._n += len(rewards)
        if time.perf_counter() - self._last >= self.every_s:
            self._say()
        return True

    def _on_training_end(self) -> None:
        self._say()

    def _say(self) -> None:
        now = time.perf_counter()
        total = int(getattr(self.model, "_total_timesteps", 0) or 0)
        done = int(self.num_timesteps)
        of = f"/{total:,} steps ({100 * done / total:.0f} %)" if total else " steps"
        reward = f", reward per decision {self._sum / self._n:+.3f} since the last line" if self._n else ""
        print(
            f"{self.prefix}: {done:,}{of}, {(now - self._t0) / 60:.1f} min{reward}",
            file=self.stream or sys.stderr,
            flush=True,
        )
        self._last, self._sum, self._n = now, 0.0, 0
