"""matplotlib for the package's figures, imported only when a figure is asked for."""

from __future__ import annotations

__all__ = ["pyplot"]


def pyplot(hint: str = ""):
    """``matplotlib.pyplot`` on the non-interactive Agg backend; :class:`~marine_fdi_env.errors.MissingExtra`
    naming the ``plots`` extra (and ``hint``, e.g. an option that skips the plots) when matplotlib is missing."""
    try:
        import matplotlib
    except ImportError:
        from .errors import MissingExtra

        raise MissingExtra("matplotlib", "plots", hint) from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt
