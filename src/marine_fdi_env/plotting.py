"""matplotlib for the package's figures, imported only when a figure is asked for."""

from __future__ import annotations

__all__ = ["pyplot"]


def pyplot(hint: str = ""):
    """``matplotlib.pyplot`` on the non-interactive Agg backend; RuntimeError naming the ``plots`` extra (and
    ``hint``, e.g. an option that skips the plots) when matplotlib is missing."""
    try:
        import matplotlib
    except ImportError:
        raise RuntimeError(
            "plots need matplotlib: pip install 'marine-fdi-env[plots]'" + (f" ({hint})" if hint else "")
        ) from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt
