"""The package version (one place; the layers below the package ``__init__`` import it from here)."""

__version__ = "0.1.0"
