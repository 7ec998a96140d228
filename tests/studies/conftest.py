"""Every test here checks a study of the repository's ``studies/`` (study trials, bounds, statistical
thresholds) and carries the ``study`` marker: ``python -m pytest -m study`` runs them (CI does)."""

import pytest


def pytest_collection_modifyitems(config, items):
    for item in items:
        if "tests/studies/" in item.nodeid:
            item.add_marker(pytest.mark.study)
