import numpy as np
import pytest

from lerobot_physvla import metrics


def test_precision_efficiency_and_wilson():
    assert metrics.precision([0.2, 0.05, 0.3]) == pytest.approx(0.5)
    assert metrics.precision([0.5]) == 0.0
    assert metrics.efficiency(True, 70, 280) == pytest.approx(0.75) and metrics.efficiency(False, 70, 280) == 0
    lo, hi = metrics.wilson_interval(5, 10)
    assert lo == pytest.approx(0.2366, abs=1e-3) and hi == pytest.approx(0.7634, abs=1e-3)
    for k in range(31):  # inside [0, 1] at the ends too (0 of 30 printed "[-0%, 11%]" before)
        lo, hi = metrics.wilson_interval(k, 30)
        assert 0.0 <= lo <= k / 30 <= hi <= 1.0
    assert metrics.wilson_interval(0, 30)[0] == 0.0 and metrics.wilson_interval(30, 30)[1] == 1.0


def test_smooth_motion_scores_better_than_jittery_motion():
    t = np.linspace(0, 2, 41)
    smooth = np.stack([0.2 * (1 - np.cos(np.pi * t / 2)), 0 * t, 0 * t], axis=1)
    jitter = smooth + np.random.default_rng(0).normal(0, 0.002, smooth.shape)
    dt = 0.05
    assert metrics.mean_jerk(smooth, dt) < metrics.mean_jerk(jitter, dt)
    assert metrics.stability(smooth, dt) > metrics.stability(jitter, dt)
    assert metrics.sparc(smooth, dt) > metrics.sparc(jitter, dt)  # closer to 0 is smoother
    assert metrics.ldlj(smooth, dt) > metrics.ldlj(jitter, dt)
