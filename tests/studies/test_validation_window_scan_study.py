"""The local-departure scan (:mod:`marine_fdi_env.validation.select.window_scan`): its p-value holds its level on pure
noise, also when the noise is larger than the tolerance, it finds a bump of a few tolerances, and the noise level of
a dataset is estimated blind to biases, trends and one channel's effect."""

from __future__ import annotations

import pytest

from studies.validation.study import trial


def test_an_out_of_library_bump_below_the_old_bonferroni_bar_is_reported():
    """Study trial e69: a 25 K bump on the cooler-outlet temperature around 83 % load (4.2 tolerances beyond what a
    sensor calibration could absorb).  The scan gives p = 0.0025 on the channel: missed at 1 % family-wise over 13
    channels with the Bonferroni p-value (0.0051), reported at the 5 % family-wise level of unexplained findings."""
    tr = trial("e", 69)
    assert tr["unexplained_right_channel"] and tr["unexplained_right_region"], tr["unexplained"]
    assert not tr["named_any"]
    assert tr["effect_size"]["beyond_calibration"] == pytest.approx(4.23, abs=0.05)
