"""transfer-v3: a part-load profile family and sensor-noise scales no training or calibration config
draws (the learned agents' noise grid holds neither 1.3x nor 0.6x), faults at 1-3x their limit."""

from __future__ import annotations

import numpy as np
import pytest

from marine_fdi_env.benchmark.suites import TRANSFER_V3_NOISE_SCALES, build_suite, load_suite
from marine_fdi_env.engine.profiles import make_profile
from marine_fdi_env.engine.simulator import Simulator
from marine_fdi_env.envs.detectability import sampling_scale
from marine_fdi_env.envs.scenario_sampler import HELD_OUT_PROFILES
from tests.integration.test_transfer_v2 import training_configs, training_specs


def test_transfer_v3_is_slow_steaming_at_the_two_noise_scales():
    suite = load_suite("transfer-v3")
    scs = suite.scenarios
    assert len(scs) == 128 and suite["env"]["reward"] == "v1"
    assert {s.profile.split(":")[0] for s in scs} == {"slowsteaming"}
    assert [s.noise_scale for s in scs[:4]] == [1.3, 0.6, 1.3, 0.6]
    assert sum(s.noise_scale == 1.3 for s in scs) == sum(s.noise_scale == 0.6 for s in scs) == 64
    assert {len(s.faults) for s in scs} == {0, 1, 2}
    scales = [x for s in scs for x in s.magnitude_scales]
    assert 1.0 <= min(scales) and max(scales) <= 3.0
    for s in scs:
        for f, x in zip(s.faults, s.magnitude_scales):
            assert abs(f.magnitude) == pytest.approx(
                x * sampling_scale(f.fault_id) / (60.0 if f.kind == "drift" else 1.0)
            )
    assert build_suite("transfer-v3")["scenarios"] == [s.to_dict() for s in scs]  # frozen


def test_no_training_or_calibration_config_can_draw_transfer_v3():
    assert "slowsteaming" in HELD_OUT_PROFILES
    configs = training_configs()
    assert any("robust" in k for k in configs)
    for name, (cfg, noise) in configs.items():
        assert "slowsteaming" not in {f for f, w in cfg.profiles if w > 0}, name
        assert not noise & set(TRANSFER_V3_NOISE_SCALES), name
    assert any("noise_scales" in spec for spec in training_specs().values())


def test_slow_steaming_is_what_it_says_and_the_engine_follows_it():
    p = make_profile("slowsteaming:seed=2,u_mean=0.4,drift=0.1,amplitude=0.1,period=8", 300.0)
    t, u = np.array(p.times), np.array(p.values)
    early, late = u[t < 60].mean(), u[t > 240].mean()
    assert early == pytest.approx(0.4 * 0.92, rel=0.05) and late == pytest.approx(0.4 * 1.08, rel=0.05)
    level = 0.4 * (1 + 0.1 * (2 * t / 300 - 1))
    assert np.all(np.abs(u / level - 1) <= 0.1 + 1e-12) and np.ptp(u / level) > 0.1
    with pytest.raises(ValueError, match="drift"):
        make_profile("slowsteaming:drift=1.5")
    lo = make_profile("slowsteaming:seed=5,u_mean=0.3,drift=-0.1,amplitude=0.12,period=6", 300.0)
    res = Simulator(n_engines=2, seeds=[1, 2], profiles=[p, lo], noise_scale=1.3).run(60.0)
    assert not res.failures and np.all(np.isfinite(res.measurements))
