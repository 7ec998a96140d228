"""matplotlib for the validation package's figures, imported only when a figure is asked for."""

from __future__ import annotations

__all__ = ["pyplot"]


def pyplot():
    """``matplotlib.pyplot`` on the non-interactive Agg backend; RuntimeError naming the extra when it is missing."""
    try:
        import matplotlib
    except ImportError:
        raise RuntimeError("plots need matplotlib: pip install 'marine-fdi-env[plots]'") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt
