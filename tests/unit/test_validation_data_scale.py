"""Residual structure judged against the data's own scatter where a tolerance is loose (validation/data_scale.py)."""

from __future__ import annotations

import numpy as np
import pytest

from marine_fdi_env.validation.data_scale import channel_noise, channel_scales
from marine_fdi_env.validation.problem import Problem
from marine_fdi_env.validation.selection import select_causes
from marine_fdi_env.validation.synthesize import synthesize
from studies.validation.study import loaded


def test_channel_scales_estimate_the_noise_below_the_tolerance_only():
    """Eleven channels of white noise at half their tolerance, one at twice it, 14 points: the pooled estimate of
    the quiet channels is near 0.5 tolerances (its sampling error over 10 channels x 13 differences is about 10 %,
    so 0.35-0.7 is a wide margin), and the noisy channel keeps its tolerance (None)."""
    rng = np.random.default_rng(11)
    load = np.sort(rng.uniform(0.25, 1.1, 14))
    tol = {f"c{j}": 2.0 + j for j in range(11)}
    res = {c: rng.normal(0.0, 0.5 * t, load.size) for c, t in tol.items()}
    res["c10"] = rng.normal(0.0, 2.0 * tol["c10"], load.size)
    sc = channel_scales(res, tol, load)
    assert sc["c10"] is None
    for c in list(tol)[:10]:
        assert 0.35 < sc[c] / tol[c] < 0.7, (c, sc[c] / tol[c])


def test_channel_noise_is_unbiased_on_noise_and_less_moved_by_a_bump_than_the_mean_square():
    """400 draws of 14 points of unit white noise: the median-based scatter is unbiased (median over draws within
    5 % of 1: its sampling spread over 400 draws is about 2 %); with a bump of ten noise levels on about three
    points, its median over draws stays below 1.6 while the mean-square scatter of the differences (what the
    scan's null level uses for the whole dataset) rises above 1.9: the bump touches four of 13 differences."""
    rng = np.random.default_rng(3)
    load = np.linspace(0.25, 1.1, 14)
    bump = 10.0 * np.exp(-0.5 * ((load - 0.6) / 0.06) ** 2)
    clean, robust, mean_square = [], [], []
    for _ in range(400):
        r = rng.normal(0.0, 1.0, load.size)
        clean.append(channel_noise(r, load))
        robust.append(channel_noise(r + bump, load))
        mean_square.append(np.sqrt(np.mean(np.diff(r + bump) ** 2) / 2))
    assert np.median(clean) == pytest.approx(1.0, abs=0.05)
    assert np.median(robust) < 1.6 and np.median(mean_square) > 1.9


@pytest.mark.parametrize("bump", [True, False])
def test_a_bump_below_a_loose_tolerance_is_reported_at_the_data_scale(bump):
    """A bump below a loose tolerance, small: 14 points of the base model with noise 0.5 % of each channel's typical
    reading (2.5 K on the turbine outlet, whose tolerance is 5 K) and a 10 K bump around 60 % load (two tolerances
    at its peak, four noise levels).  Judged at the tolerance, the window scan misses it; judged at the data's
    scatter it is reported on its channel, saying which scale it used; without the bump nothing is."""
    eff = (
        [
            {
                "kind": "bump",
                "family": "temperature",
                "channel": "turbine_outlet_temperature_C",
                "center": 0.6,
                "width": 0.08,
                "amplitude": 10.0,
                "relative": False,
            }
        ]
        if bump
        else []
    )
    syn = synthesize("wartsila-6l46", ["none"], points=14, noise=0.005, seed=2, effects=eff)
    sel = select_causes(Problem(loaded(syn)))
    assert sel.selected_labels == []
    local = [u for u in sel.unexplained if u["kind"] == "local"]
    if bump:
        assert [(u["channel"], u["scale"]) for u in local] == [("turbine_outlet_temperature_C", "data")]
        lo, hi = local[0]["load_range"]
        assert lo <= 0.68 and hi >= 0.52 and "judged at the data's scatter" in local[0]["text"]
    else:
        assert local == []
