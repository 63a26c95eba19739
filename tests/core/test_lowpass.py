"""The adaptive low-pass: off for a smooth policy, strong for a jittery one, never on the gripper."""

import numpy as np

from lerobot_physvla.core.config import PhysVLAConfig
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.core.lowpass import LP_ACTIVE, N_LP_MEM, adaptive_lowpass
from lerobot_physvla.core.state import OK

from conftest import make_state

CAPS_OFF = (0.0, 0.0, 0.0, 0.0)


def _run(actions, **cfg):
    c = Corrector(PhysVLAConfig(mode="phys", phase_caps=CAPS_OFF, lowpass="adaptive", **cfg))
    st = make_state(obj=(0.5, 0.0, 0.9))  # approach phase
    return np.array([c(a[None], st)[0] for a in actions])


def test_a_smooth_policy_is_executed_as_it_is():
    t = np.arange(60)
    raw = np.zeros((60, 7))
    raw[:, 0] = 0.5 * np.sin(t / 10.0)  # smooth: step-to-step changes ~0.05, noise estimate < lo
    raw[:, 6] = -1.0
    np.testing.assert_array_equal(_run(raw), raw)


def test_a_jittery_policy_is_smoothed_on_the_position_channels_only():
    rng = np.random.default_rng(0)
    raw = np.zeros((200, 7))
    raw[:, :2] = rng.normal(0.0, 0.3, (200, 2))
    raw[:, 3:6] = rng.normal(0.0, 0.3, (200, 3))
    raw[:, 6] = np.where(rng.uniform(size=200) < 0.5, -1.0, 1.0)
    raw = np.clip(raw, -1.0, 1.0)
    out = _run(raw, lowpass_alpha_max=0.8)
    # after the roughness estimate settles, the x, y jitter is cut (alpha -> alpha_max = 0.8:
    # an EMA keeps sqrt((1 - a) / (1 + a)) = 0.33 of white noise's std)
    assert out[50:, :2].std() < 0.45 * raw[50:, :2].std()
    np.testing.assert_array_equal(out[:, 2], raw[:, 2])  # z was smooth (all zero): untouched
    np.testing.assert_array_equal(out[:, 3:], raw[:, 3:])  # rotation and gripper never filtered
    assert np.all(np.abs(out) <= 1.0)


def test_only_in_the_listed_phases():
    rng = np.random.default_rng(1)
    raw = np.zeros((100, 7))
    raw[:, :2] = rng.normal(0.0, 0.3, (100, 2))
    np.testing.assert_array_equal(_run(raw, lowpass_phases="grasp,transport"), raw)  # state: approach
    assert not np.array_equal(_run(raw, lowpass_phases="approach"), raw)


def test_memory_moves_only_on_commit_and_a_pass_through_breaks_the_history():
    mem = np.zeros((1, N_LP_MEM))
    out = np.full((1, 7), 0.5)
    pos, mask = np.array([0, 1, 2]), np.ones(4, np.int64)
    args = (np.zeros(1, np.int8), np.array([OK], np.int8), pos, mask, 0.8, 0.05, 0.2)
    adaptive_lowpass(out.copy(), out, *args, mem, False, np.zeros(1))
    assert not mem.any()
    adaptive_lowpass(out.copy(), out, *args, mem, True, np.zeros(1))
    assert mem[0, LP_ACTIVE] == 1.0
    bad = (args[0], np.array([1], np.int8), *args[2:])
    adaptive_lowpass(out.copy(), out, *bad, mem, True, np.zeros(1))
    assert mem[0, LP_ACTIVE] == 0.0
