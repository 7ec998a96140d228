"""The render mode an environment is made with: an unsupported one warns and falls back to none."""

from __future__ import annotations

from collections.abc import Sequence

from gymnasium import logger

__all__ = ["supported_render_mode"]


def supported_render_mode(render_mode: str | None, supported: Sequence[str]) -> str | None:
    """``render_mode`` if the environment supports it, else ``None`` after a warning.

    Gymnasium's own environments warn and go on without rendering when asked for a mode they do not
    have; so do these, so that tools passing ``render_mode="rgb_array"`` by default (Stable-Baselines3's
    ``make_vec_env``) work unchanged."""
    if render_mode is None or render_mode in supported:
        return render_mode
    logger.warn(
        f"render_mode={render_mode!r} is not supported (supported: {list(supported) or 'none'}); rendering is off"
    )
    return None
