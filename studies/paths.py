"""Where the studies write: the repository's own folders (a study runs from a checkout, not an install)."""

from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGE_DATA = REPO / "src" / "marine_fdi_env" / "data"  # shipped data the package loads (cells, calibrations)
DOCS_DATA = REPO / "docs" / "data"  # the data behind the docs' tables
MODELS = REPO / "training" / "models"  # the shipped learned agents
