"""The perception model between a state source and the corrector: each fault does what it says, to the
poses only, and reaches the corrector, never the policy."""

from __future__ import annotations

import sys
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from lerobot_physvla.core.state import PhysState, field_offsets
from lerobot_physvla.sources.perception import Perception, PerceptionConfig, PoseFaults

F = field_offsets(7)


def _true_states(steps: int, rng=None) -> list[np.ndarray]:
    """One env's packed states over an episode: the object carried along x, the target still."""
    out = []
    for t in range(steps):
        s = PhysState.empty(1, 7)
        s.valid[:], s.episode_step[:], s.dt[:] = 1.0, t, 0.05
        s.eef_pos[:] = (0.01 * t, 0.0, 1.0)
        s.obj_pos[:] = (0.01 * t, 0.02, 0.95)
        s.obj_rest_z[:] = 0.9
        s.target_pos[:] = (0.3, -0.1, 0.9)
        s.q[:] = 0.1 * t
        out.append(s.pack().copy())
    return out


def _seen(faults: PerceptionConfig, steps=200, seed=3) -> tuple[list[np.ndarray], list[np.ndarray], Perception]:
    per = Perception(faults)
    per.reset(seed=seed)
    true = _true_states(steps)
    return true, [per.apply(x) for x in true], per


def _pose(row, key):
    return row[0, F[key]:F[key] + 3]


def test_exact_perception_changes_nothing():
    true, seen, _ = _seen(PerceptionConfig())
    assert all(np.array_equal(a, b, equal_nan=True) for a, b in zip(true, seen))


def test_a_bias_is_one_offset_of_its_length_per_episode_on_the_poses_only():
    true, seen, per = _seen(PerceptionConfig.both(bias_m=0.02))
    offs = np.array([_pose(s, "obj_pos") - _pose(t, "obj_pos") for t, s in zip(true, seen)])
    np.testing.assert_allclose(offs, offs[:1].repeat(len(offs), 0))  # the same offset every step
    assert np.linalg.norm(offs[0]) == pytest.approx(0.02)
    assert seen[0][0, F["obj_rest_z"]] - 0.9 == pytest.approx(offs[0][2])  # the rest height, read at reset, too
    tgt = _pose(seen[0], "target_pos") - _pose(true[0], "target_pos")
    assert np.linalg.norm(tgt) == pytest.approx(0.02) and not np.allclose(tgt, offs[0])  # its own draw
    for t, s in zip(true, seen):  # every other field untouched
        mask = np.ones(t.shape[1], bool)
        mask[F["obj_pos"]:F["target_pos"] + 3] = False
        np.testing.assert_array_equal(t[0, mask], s[0, mask])
    per.reset(seed=4)  # a new episode draws a new bias
    again = per.apply(true[0])
    assert not np.allclose(_pose(again, "obj_pos") - _pose(true[0], "obj_pos"), offs[0])
    # the same seed draws the same bias: paired across configurations
    assert np.array_equal(_seen(PerceptionConfig.both(bias_m=0.02))[1][5], seen[5], equal_nan=True)


def test_noise_has_its_sigma_per_axis_and_no_bias():
    true, seen, _ = _seen(PerceptionConfig.both(noise_m=0.01), steps=2000)
    err = np.array([_pose(s, "obj_pos") - _pose(t, "obj_pos") for t, s in zip(true, seen)])
    np.testing.assert_allclose(err.std(axis=0), 0.01, rtol=0.1)
    np.testing.assert_allclose(err.mean(axis=0), 0.0, atol=0.0015)


def test_a_lag_reports_the_pose_of_lag_steps_ago_with_its_age_and_nothing_before_the_first():
    true, seen, _ = _seen(PerceptionConfig(object=PoseFaults(lag_steps=3)))
    for t in range(3):
        assert np.isnan(_pose(seen[t], "obj_pos")).all()  # nothing reported yet: missing
    for t in range(3, 50):
        np.testing.assert_array_equal(_pose(seen[t], "obj_pos"), _pose(true[t - 3], "obj_pos"))
        assert seen[t][0, F["pose_age"]] == 3
        np.testing.assert_array_equal(_pose(seen[t], "target_pos"), _pose(true[t], "target_pos"))  # not lagged


def test_dropouts_hold_the_last_pose_for_their_runs_and_the_age_counts_them():
    true, seen, per = _seen(PerceptionConfig(target=PoseFaults(dropout=0.1, dropout_run=5)), steps=5000)
    ages = np.array([s[0, F["pose_age"]] for s in seen])
    assert 0.06 < (ages > 0).mean() < 0.14  # about a tenth of the steps
    k = int(np.flatnonzero(ages > 0)[0])
    assert list(ages[k:k + 5]) == [1, 2, 3, 4, 5] and ages[k + 5] == 0  # one run of 5, held, then fresh
    held = _pose(seen[k - 1], "target_pos")
    assert all(np.array_equal(_pose(seen[k + j], "target_pos"), held) for j in range(5))
    assert per.counts["held"] == int((ages > 0).sum())


def test_an_episode_step_that_goes_back_starts_a_new_episode():
    per = Perception(PerceptionConfig.both(bias_m=0.03), seed=1)
    true = _true_states(5)
    first = [per.apply(x) for x in true]
    second = [per.apply(x) for x in true]  # episode_step 4 -> 0: a reset
    assert not np.allclose(_pose(first[0], "obj_pos"), _pose(second[0], "obj_pos"))


def test_bad_faults_are_clear_errors():
    for bad in ({"bias_m": -1.0}, {"noise_m": float("nan")}, {"lag_steps": -1}, {"dropout": 1.0}, {"dropout_run": 0}):
        with pytest.raises(ValueError, match="perception"):
            PoseFaults(**bad)
    with pytest.raises(ValueError, match="unknown fault"):
        PerceptionConfig.from_dict({"bias": 0.01})
    assert PerceptionConfig.from_dict({"object": {"bias_m": 0.01}}).target.exact
    assert PerceptionConfig.both(bias_m=0.01, noise_m=0.005).error_bound_m == pytest.approx(0.02)


# ---- the faults reach the corrector, not the policy ------------------------------------------------------

class _Scene:
    """A scene whose object sits still; it records nothing but its steps."""

    horizon, stop_on_success = 6, False

    def __init__(self):
        self.t = 0

    def reset(self, seed):
        self.t = 0

    def read(self):
        s = PhysState.unpack(_true_states(10)[self.t])
        return s

    def step(self, a):
        self.t += 1
        return False, 0.0


class _Recorder:
    def __init__(self):
        self.seen = []

    def reset(self, seed):
        pass

    def act(self, scene, st):
        self.seen.append(st.pack().copy())
        return np.zeros(7)


def test_in_the_harness_the_policy_reads_the_scene_and_the_corrector_the_perceived_pose():
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "eval"))
    import harness

    from lerobot_physvla.core.config import PhysVLAConfig
    from lerobot_physvla.core.corrector import Corrector

    got = []

    class Spy(Corrector):
        def correct_packed(self, actions, flat):
            got.append(np.array(flat, copy=True))
            return super().correct_packed(actions, flat)

    policy = _Recorder()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        harness.run_episode(_Scene(), Spy(PhysVLAConfig()), policy, 0, Perception(PerceptionConfig.both(bias_m=0.02)))
    true = _true_states(6)
    assert len(got) == len(policy.seen) == 6
    for t in range(6):
        np.testing.assert_array_equal(policy.seen[t], true[t])  # the policy: exact
        off = _pose(got[t], "obj_pos") - _pose(true[t], "obj_pos")
        assert np.linalg.norm(off) == pytest.approx(0.02)  # the corrector: biased


def test_in_lerobot_eval_the_state_export_carries_the_faults_and_the_policys_observation_does_not():
    import gymnasium as gym
    from gymnasium import spaces

    from lerobot_physvla.envs.libero_physvla import LiberoPhysVLAEnvConfig, PhysVLAStateExport
    from lerobot_physvla.processor.physvla_processor import STATE_KEY

    cfg = LiberoPhysVLAEnvConfig(task="libero_spatial", cameras=False, pose_bias_m=0.02, pose_lag_steps=1)
    assert cfg.perception.object == PoseFaults(bias_m=0.02, lag_steps=1)
    with pytest.raises(ValueError, match="perception"):
        LiberoPhysVLAEnvConfig(task="libero_spatial", pose_dropout=2.0)
    class Fake(gym.Env):  # just enough of lerobot's LiberoEnv for the state-export wrapper
        task_id, camera_name, _env = 3, [], object()  # _env: LIBERO "built" (no real source: it stays None)
        observation_space = spaces.Dict({"robot_state": spaces.Dict({})})
        action_space = spaces.Box(-1, 1, (7,))

        def reset(self, **kw):
            return {"robot_state": {}}, {}

    fake = Fake()
    wrapper = PhysVLAStateExport(fake, cameras=False, perception=cfg.perception)
    true = _true_states(4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        wrapper.reset(seed=5)
    wrapper.source = SimpleNamespace(read_packed=lambda: true[wrapper.k][0], step=lambda: None)
    rows, envs = [], []
    for k in range(4):
        wrapper.k = k
        obs = wrapper._augment({"robot_state": {}}, False)
        rows.append(obs["robot_state"][STATE_KEY])
        envs.append(obs["environment_state"])
    for k in range(4):
        np.testing.assert_array_equal(envs[k], np.concatenate([_pose(true[k], "obj_pos"), _pose(true[k], "target_pos")]))
    assert np.isnan(rows[0][F["obj_pos"]:F["obj_pos"] + 3]).all()  # lag 1: nothing reported at the first step
    for k in range(1, 4):
        off = rows[k][F["obj_pos"]:F["obj_pos"] + 3] - _pose(true[k - 1], "obj_pos")
        assert np.linalg.norm(off) == pytest.approx(0.02) and rows[k][F["pose_age"]] == 1
